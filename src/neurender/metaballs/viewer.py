"""The report's interactive metaballs view: the demo animation (:mod:`neurender.metaballs.demo`)
by every network and by the ray marcher, a frame scrubber, and each network's silhouette
difference from the ray marcher as an overlay.

See :mod:`neurender.viewer_data` (kind ``frames``). Images are the demo's deferred shading
as display values (uint8 RGB, ``W x W``); overlays are RGBA
(:func:`neurender.viewer_data.mask_difference`: red where only the network covers a
pixel, blue where only the ray marcher does; silhouettes by depth,
:func:`neurender.metaballs.gbuffers.silhouette_depth`).
"""

from __future__ import annotations

from neurender import io, viewer_data
from neurender.metaballs.demo import RAY_MARCHING, Sequence

OVERLAY_LABEL = "silhouette difference from ray marching (red: extra, blue: missing)"


def demo_view(sequence: Sequence, names: list[str], width: int) -> dict:
    """The ``frames`` viewer data of a rendered demo.

    Args:
        sequence: :func:`neurender.metaballs.demo.render_sequence`'s result for renderers
            ``names`` (in that order): per frame a ``(3, W, (M + 1) W)`` picture and
            ``M + 1`` silhouettes, the ray marcher's last.
        names: the ``M`` networks' labels.
        width: ``W``, the image width in pixels.
    """
    panels = [*names, RAY_MARCHING]
    frames: dict[str, list] = {p: [] for p in panels}
    overlay: dict[str, list] = {n: [] for n in names}
    for picture, silhouettes in zip(sequence.pictures, sequence.silhouettes, strict=True):
        if picture.shape[-1] != width * len(panels) or len(silhouettes) != len(panels):
            raise ValueError(
                f"demo frame of shape {tuple(picture.shape)} with {len(silhouettes)} "
                f"silhouettes: expected {len(panels)} panels of width {width}"
            )
        image = io.to_uint8(picture.permute(1, 2, 0).numpy())
        for k, panel in enumerate(panels):
            frames[panel].append(image[:, k * width : (k + 1) * width])
        truth = silhouettes[-1].numpy()
        for name, mask in zip(names, silhouettes, strict=False):
            overlay[name].append(viewer_data.mask_difference(mask.numpy(), truth))
    return viewer_data.frames_data(
        frames, "frame", viewer_data.display_scale(width), overlay, OVERLAY_LABEL
    )
