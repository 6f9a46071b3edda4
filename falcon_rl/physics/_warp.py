"""Optional Warp import shared by the subsystem modules.

Each subsystem module defines its ``@wp.func`` twin with :func:`warp_func`. When warp-lang is not
importable the twins become placeholders that raise on use, so the torch backend keeps working.
Kernel compilation is lazy (first launch) and cached on disk by Warp; :func:`init_warp` runs
``wp.init()`` once, quietly (Warp's module-load messages would otherwise reach stdout).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import torch

try:
    import warp as wp
except ImportError:  # pragma: no cover - warp-lang is a core dependency
    wp = None  # type: ignore[assignment]

_initialised = False


def warp_available() -> bool:
    """True when warp-lang can be imported."""
    return wp is not None


def warp_cuda_available() -> bool:
    """True when both torch and Warp see a CUDA device (the warp backend can run on ``cuda``)."""
    import torch

    if wp is None or not torch.cuda.is_available():
        return False
    return init_warp().get_cuda_device_count() > 0


def warp_device(device: torch.device) -> str:
    """Warp device name of a torch device ("cpu" or "cuda:<index>"); ValueError for other devices."""
    import torch

    if device.type == "cpu":
        return "cpu"
    if device.type == "cuda":
        index = device.index if device.index is not None else torch.cuda.current_device()
        return f"cuda:{index}"
    raise ValueError(f"Warp runs on cpu or cuda devices, not {device}")


def init_warp() -> Any:
    """Initialise Warp once (quiet) and return the ``warp`` module."""
    global _initialised
    if wp is None:
        raise RuntimeError("the warp backend needs the warp-lang package (pip install warp-lang)")
    if not _initialised:
        if hasattr(wp, "LOG_WARNING"):
            wp.config.log_level = wp.LOG_WARNING
        else:  # older Warp releases
            wp.config.quiet = True
        wp.init()
        _initialised = True
    return wp


def capture_cpu_graph(launch: Any) -> Any | None:
    """``launch`` (a launch recorded with ``record_cmd=True`` on the CPU) captured as a Warp CPU graph,
    for ``wp.capture_launch``: the graph replays it in C++ with the argument struct built once, about
    5 us less per call than ``launch.launch()``, which builds it again in Python (what a one-env step
    pays). Capturing records and does not run the launch. None where this Warp cannot capture on the
    CPU (releases before CPU graphs), that cannot record this launch, or when a capture is already open:
    replay the launch itself then."""
    warp = init_warp()
    try:
        warp.capture_begin(device="cpu")
    except (RuntimeError, ValueError, TypeError, NotImplementedError):
        return None
    recorded = False
    try:
        launch.launch()
        recorded = True
    except RuntimeError:  # a launch this Warp cannot record (e.g. one without its argument list)
        pass
    finally:
        graph = warp.capture_end(device="cpu")
    return graph if recorded else None


#: Options of every Warp kernel module here: forward kernels only. Nothing differentiates through
#: them, and the adjoints Warp compiles by default multiplied the compile time (a cold CPU build of
#: the altitude env 77.6 s -> 20.7 s without them; a cold CUDA build takes minutes even so).
KERNEL_OPTIONS: dict[str, Any] = {"enable_backward": False}


def forward_only(module_name: str) -> None:
    """Compile the Warp kernels of module ``module_name`` with :data:`KERNEL_OPTIONS` (no adjoints)."""
    if wp is not None:
        wp.set_module_options(dict(KERNEL_OPTIONS), module_name)


def warp_func(fn: Callable[..., Any]) -> Any:
    """``@wp.func`` when Warp is available, else a placeholder that raises when called."""
    if wp is not None:
        return wp.func(fn)

    def unavailable(*_args: Any, **_kwargs: Any) -> Any:
        raise RuntimeError("warp-lang is not installed")

    return unavailable


def warp_struct(cls: type) -> Any:
    """``@wp.struct`` when Warp is available, else the plain class."""
    return wp.struct(cls) if wp is not None else cls


def vector_type(length: int) -> Any:
    """A float32 Warp vector type of ``length`` components (None without Warp)."""
    return wp.types.vector(length=length, dtype=wp.float32) if wp is not None else None
