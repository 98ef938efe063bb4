"""Config keys the metaballs' job tests pass: the thesis's scenes and field, as the
default config gives them (:data:`neurender.metaballs.rule_keys.SCENE`)."""

from neurender.metaballs import rule_keys
from neurender.method import Rule

_DEFAULT = {"metaballs": {"family": "thesis", "kernel": {"name": "inverse_square"}}}
#: The ``kernel`` params of a job that reads the field.
KERNEL = Rule("test", params=(rule_keys.KERNEL,)).job_params(_DEFAULT, {})
#: The scene keys of an examples job beside ``balls`` and ``radius``.
THESIS_SCENES = {"family": "thesis", **KERNEL}
