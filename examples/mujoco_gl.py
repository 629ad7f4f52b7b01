"""MuJoCo's GL backend (``MUJOCO_GL``): checked before TorchRL imports MuJoCo, which reads the variable."""

from __future__ import annotations

import importlib
import os

GL_HELP = (
    "MuJoCo renders offscreen through a GL backend chosen by the MUJOCO_GL environment variable. "
    "On a machine without a display use MUJOCO_GL=egl (Debian/Ubuntu: apt-get install libegl1 libgl1, "
    "plus libegl-mesa0 without a GPU) or MUJOCO_GL=osmesa (apt-get install libosmesa6); "
    "MUJOCO_GL=glfw needs a display."
)


def check_mujoco_gl() -> None:
    """Fails clearly if ``MUJOCO_GL`` names a backend whose library is missing (MuJoCo loads it on import)."""
    if "MUJOCO_GL" not in os.environ:
        return  # gymnasium tries glfw, egl, osmesa in turn when an env first renders
    try:
        importlib.import_module("mujoco")
    except Exception as err:  # PyOpenGL fails with AttributeError, ImportError, ...
        raise RuntimeError(
            f"MuJoCo cannot load MUJOCO_GL={os.environ['MUJOCO_GL']!r} ({type(err).__name__}: {err}). {GL_HELP}"
        ) from err
