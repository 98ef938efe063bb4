import numpy as np

from neurender.timing import peak_memory, timed


def test_peak_memory_sees_what_the_call_allocated_and_freed():
    def allocate(mb):
        block = np.ones(mb * 2**20, dtype=np.uint8)  # touched: resident, not only reserved
        return int(block[::4096].sum())

    out, added = peak_memory(allocate, 200)
    assert out == 200 * 2**20 // 4096
    assert 150 * 2**20 < added < 400 * 2**20


def test_peak_memory_of_a_call_that_allocates_nothing_is_small():
    out, added = peak_memory(lambda: 3)
    assert out == 3 and added < 20 * 2**20


def test_timed_returns_the_last_result_of_its_calls():
    calls = []
    out, seconds = timed(lambda: calls.append(1) or len(calls), repeats=3, warmup=2)
    assert out == 5 and len(calls) == 5 and seconds >= 0
