"""A rule's declared params (:attr:`neurender.method.Rule.params`): the dict a job gets, in
the declared order, and the config keys each job reads, conditional ones only where their
condition holds."""

import pytest

from neurender.method import Given, Group, Rule, Value, When, wildcard

CONFIG = {
    "seed": 3,
    "prt": {"n_bands": 4, "frames": {"train": 6, "test": 2}, "directions": 64},
    "kernel": {"name": "wyvill", "support": 2.0},
}


def _test_split(cfg, wildcards):
    return wildcards["split"] == "test"


RULE = Rule(
    "stage",
    params=(
        "prt.n_bands",
        wildcard("split"),
        "seed",
        When(_test_split, ("prt.frames",)),
        Group("kernel", ("kernel.name", When(lambda c, w: False, ("kernel.support",)))),
        Value("rays", lambda cfg, wc: cfg["prt"]["directions"] * 2, ("prt.directions",)),
        Given("files"),
    ),
)


def test_a_jobs_params_hold_each_entry_by_its_last_name_in_the_declared_order():
    params = RULE.job_params(CONFIG, {"split": "test"}, {"files": ["a.yaml"]})
    assert list(params.items()) == [
        ("n_bands", 4),
        ("split", "test"),
        ("seed", 3),
        ("frames", {"train": 6, "test": 2}),
        ("kernel", {"name": "wyvill"}),
        ("rays", 128),
        ("files", ["a.yaml"]),
    ]


def test_a_condition_that_fails_leaves_its_keys_out_of_the_params_and_the_reads():
    params = RULE.job_params(CONFIG, {"split": "train"}, {"files": []})
    assert "frames" not in params
    assert RULE.reads(CONFIG, {"split": "train"}) == {
        "prt.n_bands",
        "seed",
        "kernel.name",
        "prt.directions",
    }
    assert RULE.reads(CONFIG, {"split": "test"}) - RULE.reads(CONFIG, {"split": "train"}) == {
        "prt.frames"
    }


def test_the_rules_keys_are_every_key_some_job_may_read():
    assert RULE.keys == {
        "prt.n_bands",
        "seed",
        "prt.frames",
        "kernel.name",
        "kernel.support",
        "prt.directions",
    }


def test_a_name_given_twice_is_refused():
    rule = Rule("stage", params=("seed", Value("seed", lambda cfg, wc: 0)))
    with pytest.raises(ValueError, match="seed"):
        rule.job_params(CONFIG, {})
