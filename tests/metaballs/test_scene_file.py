"""A property-based fuzz of the scenes CSV reader: whatever text a file holds, the reader
gives a clean error naming the file or balls that are all usable."""

import math
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from neurender.metaballs.scene_file import COLUMNS, NUMBERS, read_user_scenes

# Cells users and tools write: numbers in many spellings, labels that look missing or
# numeric, blanks, quotes, separators and line breaks inside cells, other scripts.
CELLS = st.one_of(
    st.sampled_from(["0", "1", "15", "0.5", "-1", "1e3", "1,5", "inf", "-inf", "nan", "1.0"]),
    st.sampled_from(["", " ", "NA", "None", "null", "N/A", "#N/A", "001", "$x$", "é", "\ufeff"]),
    st.sampled_from(['"', '""', '"a,b"', '"x\ny"', "\t", "\r", ";", "\x00"]),
    st.text(max_size=6),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
)
HEADERS = st.one_of(
    st.just(list(COLUMNS)),
    st.permutations(list(COLUMNS)),
    st.lists(st.sampled_from([*COLUMNS, "note", "", "scene"]), max_size=10),
)


LABELS = st.one_of(
    st.sampled_from(["a", "001", "1", "1.0", "NA", "None", "null", "nan", "$x$", "scène 2"]),
    st.text(min_size=1, max_size=5).filter(lambda t: t.strip()),
)
VALID = {
    "scene": LABELS,
    "x": st.floats(-3, 3),
    "y": st.floats(-3, 3),
    "z": st.floats(5, 30),
    "radius": st.floats(0.1, 3),
    "r": st.floats(0, 1),
    "g": st.floats(0, 1),
    "b": st.floats(0, 1),
}


def _cell(value) -> str:
    """A cell as a CSV writer quotes it."""
    text = repr(value) if isinstance(value, float) else str(value)
    if any(c in text for c in ',"\r\n') or text != text.strip():
        text = '"' + text.replace('"', '""') + '"'
    return text


@st.composite
def csv_texts(draw):
    """A header, then rows that are valid balls, valid balls with one cell changed, or
    random cells of about the header's width."""
    header = draw(HEADERS)
    width = len(header)
    valid = st.tuples(*(VALID.get(c, CELLS) for c in header)).map(
        lambda row: [_cell(v) for v in row]
    )
    mutated = st.tuples(valid, st.integers(0, max(0, width - 1)), CELLS).map(
        lambda t: [t[2] if k == t[1] else c for k, c in enumerate(t[0])]
    )
    noise = st.lists(CELLS, min_size=max(0, width - 1), max_size=width + 1)
    rows = draw(st.lists(st.one_of(valid, valid, mutated, noise), max_size=6))
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    lines = [",".join(header), *(",".join(r) for r in rows)]
    return newline.join(lines) + draw(st.sampled_from(["", newline, newline * 2]))


@settings(
    max_examples=200,
    deadline=None,
    derandomize=True,  # the same examples on every run
    suppress_health_check=[HealthCheck.too_slow],
)
@given(text=csv_texts(), encoding=st.sampled_from(["utf-8", "utf-8-sig", "latin-1"]))
def test_any_text_gives_a_clean_error_naming_the_file_or_usable_balls(text, encoding):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "scenes.csv"
        path.write_bytes(text.encode(encoding, errors="replace"))
        try:
            balls = read_user_scenes(path)
        except (ValueError, OSError) as err:
            assert str(path) in str(err), err
            return
    assert list(balls.columns) == list(COLUMNS) and len(balls) > 0
    assert all(isinstance(s, str) and s.strip() for s in balls["scene"])
    values = balls[list(NUMBERS)].to_numpy()
    assert values.dtype == np.float64 and np.isfinite(values).all()
    assert (balls["radius"] > 0).all() and (balls["z"] > 0).all()
    assert balls[["r", "g", "b"]].to_numpy().min() >= 0
    assert balls[["r", "g", "b"]].to_numpy().max() <= 1 and not math.isnan(values.sum())
