"""Import MuJoCo for offscreen rendering on the CPU, with errors that name what is missing.

``MUJOCO_GL`` defaults to ``egl`` (Mesa's software EGL, llvmpipe) when unset; it must be set
before ``mujoco`` is imported, so every module of the package imports ``mujoco`` from here.
"""

from __future__ import annotations

import ctypes.util
import os
import sys
import warnings

from pipeline.errors import UserError

# mujoco reads MUJOCO_GL once, at import: remember whether someone imported it before us unset
_IMPORTED_TOO_EARLY = "mujoco" in sys.modules and "MUJOCO_GL" not in os.environ
os.environ.setdefault("MUJOCO_GL", "egl")
if os.environ["MUJOCO_GL"] in ("egl", "osmesa"):
    os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

try:
    import mujoco  # noqa: E402
except ImportError as exc:  # pragma: no cover - the venv always has it
    raise ImportError(
        "the renderer needs the Python package 'mujoco' (pip install mujoco)"
    ) from exc


def _mujoco_warning(message: str) -> None:
    """MuJoCo's warnings (an unstable simulation, a full buffer) as Python runtime warnings.
    Without a handler MuJoCo prints them and appends them to ``MUJOCO_LOG.TXT`` in the working
    folder: a stray file in the user's checkout."""
    warnings.warn(f"MuJoCo: {message.strip()}", RuntimeWarning, stacklevel=2)


mujoco.set_mju_user_warning(_mujoco_warning)

_HINTS = {
    "egl": ("EGL", "apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri"),
    "osmesa": ("OSMesa", "apt-get install -y libosmesa6"),
    "glfw": ("glfw", "pip install glfw (and a display); for headless use set MUJOCO_GL=egl"),
}


class RendererUnavailable(UserError):
    """The offscreen OpenGL renderer could not start; the message says what to install or set."""


def backend_problem() -> str | None:
    """A description of a missing system library for the chosen ``MUJOCO_GL``, or None."""
    gl = os.environ.get("MUJOCO_GL", "")
    if gl not in _HINTS:
        return (
            f"MUJOCO_GL={gl!r} is not a known offscreen backend; set MUJOCO_GL=egl "
            f"(or osmesa) before running"
        )
    lib, fix = _HINTS[gl]
    if gl in ("egl", "osmesa") and ctypes.util.find_library(lib) is None:
        return f"MUJOCO_GL={gl} needs the system library lib{lib} which was not found; install it: {fix}"
    return None


def make_renderer(model, height: int, width: int):
    """``mujoco.Renderer`` for ``model``, or :class:`RendererUnavailable` naming the fix."""
    problem = backend_problem()
    if problem is not None:
        raise RendererUnavailable(problem)
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # EGL/OSMesa failures surface as assorted exception types
        gl = os.environ.get("MUJOCO_GL", "")
        fix = _HINTS.get(gl, _HINTS["egl"])[1]
        if _IMPORTED_TOO_EARLY:
            raise RendererUnavailable(
                "mujoco was imported before MUJOCO_GL was set, so it chose a windowed backend "
                f"({type(exc).__name__}: {exc}). Set MUJOCO_GL=egl in the environment (export MUJOCO_GL=egl) "
                "or import pipeline.world.renderer_env before mujoco."
            ) from exc
        raise RendererUnavailable(
            f"could not start MuJoCo's offscreen renderer with MUJOCO_GL={gl} ({type(exc).__name__}: {exc}). "
            f"Install the system packages: {fix}; or try MUJOCO_GL=osmesa with libosmesa6."
        ) from exc


__all__ = ["mujoco", "RendererUnavailable", "backend_problem", "make_renderer"]
