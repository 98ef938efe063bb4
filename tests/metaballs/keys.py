"""Config keys the metaballs' job tests pass: the thesis's scenes and field, as the
default config gives them (:func:`neurender.metaballs.method.scene_keys`)."""

from neurender.metaballs.method import kernel_keys

_DEFAULT = {"family": "thesis", "kernel": {"name": "inverse_square"}}
#: The ``kernel`` params of a job that reads the field.
KERNEL = {"kernel": kernel_keys(_DEFAULT)}
#: The scene keys of an examples job beside ``balls`` and ``radius``.
THESIS_SCENES = {"family": "thesis", **KERNEL}
