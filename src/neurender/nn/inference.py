"""Trained networks prepared for fast inference.

A DeepPRT-style renderer runs a trained network once per frame, so its cost is the
inference time of a batch of one. In PyTorch two standard steps cut that: batch norm folded
into the convolution before it (``torch.nn.utils.fusion.fuse_conv_bn_eval``: one pass
over the activations less per layer) and channels-last memory (the layout oneDNN's and
cuDNN's fastest convolution kernels use). On the CPU a network exported to ONNX and run by
ONNX Runtime is faster still: its MLAS kernels take batch-one convolutions of small images
that PyTorch sends to its unblocked native path (2.3x less time per frame for the default
DeepPRT network on 2 cores). None of these changes what the network computes beyond float
rounding, and :func:`export_onnx` checks that before it writes a file.
"""

from __future__ import annotations

import contextlib
import copy
import io
import logging
import tempfile
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.nn.utils.fusion import fuse_conv_bn_eval

from neurender.io import atomic_path
from neurender.nn.norms import centre_pixel_norm_inputs
from neurender.timing import hardware, timed

log = logging.getLogger(__name__)

# ``onnx`` and ``onnxruntime`` are imported where a file is read, written or run: together
# they take seconds to import (``onnx`` pulls in ``ml_dtypes``), and most jobs that import
# this module, through the deployment tables, do neither.


def fold_batch_norms(model: nn.Module) -> nn.Module:
    """Copy of an eval-mode ``model`` with every ``Conv2d, BatchNorm2d`` pair of an
    ``nn.Sequential`` replaced by one convolution (the batch norm by an identity)."""
    model = copy.deepcopy(model).eval()
    for seq in model.modules():
        if not isinstance(seq, nn.Sequential):
            continue
        for i in range(len(seq) - 1):
            conv, bn = seq[i], seq[i + 1]
            if isinstance(conv, nn.Conv2d) and isinstance(bn, nn.BatchNorm2d):
                seq[i] = fuse_conv_bn_eval(conv, bn)
                seq[i + 1] = nn.Identity()
    return model


def prepare_for_inference(model: nn.Module) -> nn.Module:
    """Eval-mode, batch-norm-folded, channels-last copy of ``model`` (its pixel norms'
    means folded too, :func:`neurender.nn.norms.centre_pixel_norm_inputs`).

    It computes ``model(x)`` for inputs ``(B, C, H, W)`` in either memory layout (pass
    channels-last inputs to skip a conversion).
    """
    folded = centre_pixel_norm_inputs(fold_batch_norms(model))
    return folded.to(memory_format=torch.channels_last)


#: ONNX opset of the exported files (ONNX Runtime 1.14 and later run it).
OPSET = 18


@contextlib.contextmanager
def _quiet_exporter() -> Iterator[io.StringIO]:
    """Collect what ``torch.onnx.export`` prints and silence its warnings that ask nothing
    of us: its deprecation notice (see :func:`export_onnx` for why we use the
    TorchScript-based exporter); the tracer's notes that shape checks become constants
    (only the batch axis is dynamic: every other size is the example's by contract); that
    slices with a step are not constant-folded; and that instance norm is exported with
    its input's statistics (ours keep no running statistics, so eval mode computes that
    too)."""
    chatter = io.StringIO()
    with contextlib.redirect_stdout(chatter), warnings.catch_warnings():
        warnings.filterwarnings("ignore", ".*legacy TorchScript-based ONNX export.*")
        warnings.filterwarnings("ignore", "The feature will be removed.*", DeprecationWarning)
        warnings.filterwarnings("ignore", category=torch.jit.TracerWarning)
        warnings.filterwarnings("ignore", "Constant folding - Only steps=1.*", UserWarning)
        warnings.filterwarnings("ignore", ".*operator 'instance_norm' is set to train=True.*")
        yield chatter


def export_onnx(
    model: nn.Module,
    example: torch.Tensor | tuple[torch.Tensor, ...],
    path: str | Path,
    atol: float = 1e-4,
    input_names: tuple[str, ...] = ("x",),
    rtol: float = 0.0,
    dynamic_axes: Mapping[str, Mapping[int, str]] | None = None,
    metadata: Mapping[str, str] | None = None,
) -> float:
    """Write an eval-mode CPU ``model`` as an ONNX graph with a dynamic batch axis.

    The graph maps the inputs (``x`` ``(B, C, H, W)`` float32 by default; several named
    by ``input_names``, each with the batch first) to the model's output ``y``; all other
    dimensions are fixed to the example's but those ``dynamic_axes`` names (input name ->
    axis -> its name, e.g. ``{"lights": {1: "lights"}}``). Before the file is written,
    ONNX Runtime runs it on ``example`` and a ``ValueError`` is raised if any output
    differs from PyTorch's by more than ``atol + rtol * max|y|`` (``rtol`` for outputs in
    physical units, e.g. HDR radiance, whose float32 rounding grows with their magnitude);
    the difference is stored in the file's metadata (``neurender.max_abs_diff_vs_pytorch``,
    beside ``metadata``'s keys, e.g. which network the graph is) and returned.

    The graph is traced by torch's TorchScript-based exporter (``dynamo=False``): for our
    networks it writes the same graph as the ``torch.export``-based one, which ONNX Runtime
    runs as fast, 20 to 30 times sooner (measured on 2 cores, torch 2.13: the shadowing
    DeepPRT 0.8 s against 25 s, the shipped NDR graph 6 s against 76 s), and the check
    above would refuse a file that computed anything else.

    Args:
        model: the network (traceable by ``torch.jit.trace``; on the CPU).
        example: the inputs, each with a batch of ``B >= 2`` (a batch of one would fix B).
        path: the ``.onnx`` file.
    """
    examples = (example,) if isinstance(example, torch.Tensor) else tuple(example)
    if len(examples) != len(input_names):
        raise ValueError(f"{len(examples)} example inputs for names {input_names}")
    if any(x.shape[0] < 2 for x in examples):
        shapes = [tuple(x.shape) for x in examples]
        raise ValueError(f"example {shapes}: expected inputs with a batch of B >= 2")
    model = model.eval()
    with torch.inference_mode():
        expected = model(*examples).numpy()
    with _quiet_exporter() as chatter, atomic_path(path) as tmp:
        torch.onnx.export(
            model,
            examples,
            tmp,
            dynamo=False,
            input_names=list(input_names),
            output_names=["y"],
            dynamic_axes={
                name: {0: "batch", **(dynamic_axes or {}).get(name, {})}
                for name in (*input_names, "y")
            },
            opset_version=OPSET,
        )
        log.debug("torch.onnx: %s", chatter.getvalue())
        _restore_inputs(tmp, input_names, examples)
        got = OnnxNetwork(tmp)(*(x.numpy() for x in examples))
        error = float(np.abs(got - expected).max())
        allowed = atol + rtol * float(np.abs(expected).max())
        if not error <= allowed:
            raise ValueError(
                f"{path}: ONNX Runtime differs from PyTorch by {error:.3g} (> {allowed:.3g}: "
                f"atol {atol} + rtol {rtol} x max|y| {np.abs(expected).max():.3g})"
            )
        _finish(tmp, {"neurender.max_abs_diff_vs_pytorch": f"{error:.3g}", **(metadata or {})})
    log.info("exported %s (max |ONNX - PyTorch| = %.2g)", path, error)
    return error


def onnx_metadata(path: str | Path) -> dict[str, str]:
    """The model-level metadata of an ONNX file (e.g. ``neurender.max_abs_diff_vs_pytorch``)."""
    import onnx

    return {p.key: p.value for p in onnx.load(str(path), load_external_data=False).metadata_props}


def _restore_inputs(path: Path, names: tuple[str, ...], examples: tuple[torch.Tensor, ...]) -> None:
    """Put back the inputs the exporter pruned because the graph ignores them (e.g. the
    light of an NDR variant without the SH branch), in their place, so that every file of
    a kind takes the same inputs."""
    import onnx

    model = onnx.load(str(path))
    present = {i.name: i for i in model.graph.input}
    if all(name in present for name in names):
        return
    inputs = [
        present.get(name)
        or onnx.helper.make_tensor_value_info(name, onnx.TensorProto.FLOAT, ["batch", *x.shape[1:]])
        for name, x in zip(names, examples, strict=True)
    ]
    del model.graph.input[:]
    model.graph.input.extend(inputs)
    onnx.save(model, str(path))


def _finish(path: Path, metadata: dict[str, str]) -> None:
    """Add our model metadata to the file."""
    import onnx

    model = onnx.load(str(path))
    for key, value in metadata.items():
        model.metadata_props.add(key=key, value=value)
    onnx.save(model, str(path))


#: Operators the int8 graphs compute in int8 (:func:`quantize_convolutions`): the
#: convolutions, and the ReLUs and bilinear upsamplings between them, which then pass int8
#: tensors on instead of converting to float32 and back (the shipped NDR graph, untrained,
#: one thread of an AMD EPYC, best of 7 rounds: float32 9.7 ms, the convolutions alone in
#: int8 5.4 ms, these 4.9 ms; the same largest difference from float32).
#: Concatenations stay float32: one scale for inputs of different ranges costs accuracy
#: (0.15 against 0.0009 largest difference on the same graph).
INT8_OPERATORS = ("Conv", "Relu", "Resize")


def channel_average_convolutions(model) -> list[str]:
    """Names of the ``Conv`` nodes of an ONNX ``model`` (``onnx.ModelProto``) that average
    channels: one output channel, a 1x1 kernel whose weights all equal one value, no bias (a
    :class:`~neurender.nn.norms.PixelNorm`'s means). :func:`quantize_convolutions` keeps
    them float32: the mean of squares they take spans far more than 8 bits' range (on the
    shadowing DeepPRT graphs, all convolutions in int8 raised the head's diffuse radiance
    error 1.22x, these kept float32 1.01x, and the graph stayed 1.4x faster than float32)."""
    from onnx import numpy_helper

    tensors = {t.name: t for t in model.graph.initializer}
    for node in model.graph.node:
        if node.op_type == "Constant":
            value = next((a.t for a in node.attribute if a.name == "value"), None)
            if value is not None:
                tensors[node.output[0]] = value
    names = []
    for node in model.graph.node:
        if node.op_type != "Conv" or len(node.input) > 2 or node.input[1] not in tensors:
            continue
        weight = numpy_helper.to_array(tensors[node.input[1]])
        if weight.shape[2:] == (1, 1) and weight.shape[0] == 1 and np.ptp(weight) == 0:
            names.append(node.name)
    return names


class _Feeds:
    """ONNX Runtime's calibration reader over ``feeds`` (input name -> array), once."""

    def __init__(self, feeds: Sequence[dict[str, np.ndarray]]):
        self.feeds = iter(feeds)

    def get_next(self) -> dict[str, np.ndarray] | None:
        return next(self.feeds, None)


def quantize_convolutions(
    source: str | Path, target: str | Path, calibration: Sequence[dict[str, np.ndarray]]
) -> None:
    """Write ``source`` (an ONNX file of :func:`export_onnx`) to ``target`` with its
    :data:`INT8_OPERATORS` in int8, by ONNX Runtime's static quantizer in QDQ form: weights
    int8 per output channel, activations uint8 with ranges (min and max) observed on the
    ``calibration`` feeds (each input name -> float32 array, batch first); every other
    operator stays float32, and so do the convolutions that average channels
    (:func:`channel_average_convolutions`). The int8 file computes an approximation: a
    caller measures its quality, as it measures the float32 graph's."""
    import onnx
    from onnxruntime.quantization import QuantFormat, QuantType, quant_pre_process, quantize_static

    if not calibration:
        raise ValueError(f"quantize_convolutions({source}): no calibration feeds")
    with tempfile.TemporaryDirectory(prefix="neurender-int8-") as scratch:
        prepared = Path(scratch) / "prepared.onnx"
        # ONNX's shape inference only: the symbolic one cannot follow gathers such as the
        # NDR shading's, and on failure it leaves its temporary files in the working folder.
        quant_pre_process(str(source), str(prepared), skip_symbolic_shape=True)
        averages = channel_average_convolutions(onnx.load(str(prepared)))
        with atomic_path(target) as tmp:
            quantize_static(
                str(prepared),
                str(tmp),
                _Feeds(calibration),
                quant_format=QuantFormat.QDQ,
                per_channel=True,
                activation_type=QuantType.QUInt8,
                weight_type=QuantType.QInt8,
                op_types_to_quantize=list(INT8_OPERATORS),
                nodes_to_exclude=averages,
            )
    log.info(
        "int8 graph %s from %s (%d calibration feeds; %d channel averages kept float32)",
        target,
        source,
        len(calibration),
        len(averages),
    )


class OnnxNetwork:
    """An ONNX graph run by ONNX Runtime on the CPU.

    Calling it with float32 arrays (one per graph input, in order, e.g. ``(B, C, H, W)``)
    gives the graph's first output.

    With ``threads > 1`` ONNX Runtime's pool threads spin for more work after each run;
    ``spinning=False`` makes them sleep instead, for a graph run between other work on the
    same cores (a renderer's frame: on 2 cores the spinning threads made the PyTorch
    shading after the metaballs network 13x slower).
    """

    def __init__(self, path: str | Path, threads: int = 1, spinning: bool = True):
        if not Path(path).is_file():
            raise FileNotFoundError(f"ONNX network {path} not found")
        import onnxruntime

        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = max(1, threads)
        options.inter_op_num_threads = 1
        if not spinning:
            options.add_session_config_entry("session.intra_op.allow_spinning", "0")
        self.session = onnxruntime.InferenceSession(
            str(path), options, providers=["CPUExecutionProvider"]
        )
        self.inputs = [i.name for i in self.session.get_inputs()]

    def __call__(self, *arrays: np.ndarray) -> np.ndarray:
        feed = {
            n: np.ascontiguousarray(a, np.float32) for n, a in zip(self.inputs, arrays, strict=True)
        }
        return self.session.run(None, feed)[0]


def engine_milliseconds(
    module: nn.Module, onnx_file: str | Path, inputs: tuple[torch.Tensor, ...], threads: int
) -> dict[str, float]:
    """Median milliseconds of one call (the batch in ``inputs``, usually one) by PyTorch
    (eval mode, no autograd) and by ONNX Runtime on the CPU with ``threads`` threads."""
    module = module.eval()
    session = OnnxNetwork(onnx_file, threads)
    arrays = [x.numpy() for x in inputs]
    before = torch.get_num_threads()
    torch.set_num_threads(threads)  # the same threads as ONNX Runtime's
    try:
        with torch.inference_mode():
            _, torch_s = timed(module, *inputs, repeats=21, warmup=2)
    finally:
        torch.set_num_threads(before)
    _, onnx_s = timed(session, *arrays, repeats=21, warmup=2)
    return {"pytorch": 1000 * torch_s, "onnxruntime": 1000 * onnx_s}


def least_loaded_milliseconds(
    parts: Mapping[str, tuple[nn.Module, str | Path, tuple[torch.Tensor, ...]]],
    threads: int,
    rounds: int = 3,
) -> dict[str, dict[str, float]]:
    """Per part (a module, its ONNX file and its inputs), :func:`engine_milliseconds` on
    ``threads`` threads, the parts timed in turn ``rounds`` times and each engine's least
    loaded round kept: on a shared machine, a part's time is not one busy moment's."""
    best: dict[str, dict[str, float]] = {}
    for _ in range(rounds):
        for name, (module, onnx_file, inputs) in parts.items():
            ms = engine_milliseconds(module, onnx_file, inputs, threads)
            best[name] = {e: min(t, best.get(name, ms)[e]) for e, t in ms.items()}
    return best


def part_rows(
    parts: Mapping[str, tuple[nn.Module, str | Path, tuple[torch.Tensor, ...]]],
    errors: Mapping[str, float],
    threads: int,
    rounds: int = 3,
) -> list[dict]:
    """A benchmark's rows of the parts of a graph, one per part timed by
    :func:`least_loaded_milliseconds`: ``part``, ``threads``, ``onnxruntime_ms``,
    ``pytorch_ms``, ``max_abs_diff_vs_pytorch`` (``errors[part]``, its export check),
    ``onnx_bytes`` and ``hardware``."""
    best = least_loaded_milliseconds(parts, threads, rounds)
    return [
        {
            "part": name,
            "threads": threads,
            "onnxruntime_ms": best[name]["onnxruntime"],
            "pytorch_ms": best[name]["pytorch"],
            "max_abs_diff_vs_pytorch": errors[name],
            "onnx_bytes": Path(onnx_file).stat().st_size,
            "hardware": hardware(threads, "cpu"),
        }
        for name, (_, onnx_file, _) in parts.items()
    ]
