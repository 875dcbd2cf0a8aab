"""Headless rendering of an environment: the true pose and, in the same frame, a translucent
ghost posed from the observer's estimate.

:class:`GhostRenderer` draws with MuJoCo's own renderer (``mjv_updateScene`` /
``mjr_render``) into an offscreen buffer. The ghost is the model's dynamic geoms added a
second time (``mjv_addGeoms``) from a copy of the data posed at the estimate, tinted and
translucent; where the estimate equals the truth it hides inside the true bodies. The free
camera frames the whole model (``mjv_defaultFreeCamera``: the model's centre and extent).

**OpenGL backend.** The backend named by ``MUJOCO_GL`` (``egl``, ``osmesa`` or ``glfw``) when
it is set; otherwise EGL, then OSMesa, then GLFW are tried in turn, so that rendering works on a
headless machine without setting anything (``.ci/run`` installs Debian's ``libegl1``,
``libegl-mesa0``, ``libopengl0`` and ``libgl1-mesa-dri``). When none can be made,
:class:`RenderError` says which were tried, why each failed, and what to install.
"""

from __future__ import annotations

import copy
import importlib
import os
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from hgo_mj.exceptions import HgoError

#: MUJOCO_GL value -> the mujoco module holding its GLContext
_BACKENDS = {"egl": "mujoco.egl", "osmesa": "mujoco.osmesa", "glfw": "mujoco.glfw"}
#: the ghost's colour: a translucent green
GHOST_RGBA = (0.1, 0.9, 0.5, 0.45)
_DYNAMIC = int(mujoco.mjtCatBit.mjCAT_DYNAMIC)
_ALL = int(mujoco.mjtCatBit.mjCAT_ALL)


class RenderError(HgoError, RuntimeError):
    """No OpenGL backend could be made for rendering."""


#: the process's one OpenGL context and its backend (made on first use, never freed: freeing
#: an EGL context tore down the display under the others, whose frames then came out black)
_CONTEXT: list[tuple[Any, str]] = []


def gl_context() -> tuple[Any, str]:
    """The process's offscreen OpenGL context, made current, and its backend's name. Every
    renderer draws into its own offscreen framebuffer (``mjr_setBuffer``) in this context.

    Raises
    ------
    RenderError
        No backend could be made: the message lists each one tried with its error."""
    if _CONTEXT:
        _CONTEXT[0][0].make_current()
        return _CONTEXT[0]
    wanted = os.environ.get("MUJOCO_GL", "").strip().lower()
    order = [wanted] if wanted else ["egl", "osmesa", "glfw"]
    tried = []
    for name in order:
        if name not in _BACKENDS:
            tried.append(f"{name} (not one of {sorted(_BACKENDS)})")
            continue
        try:
            ctx = importlib.import_module(_BACKENDS[name]).GLContext(64, 64)
            ctx.make_current()
            _CONTEXT.append((ctx, name))
            return ctx, name
        except Exception as exc:  # noqa: BLE001 - each backend fails in its own way
            tried.append(f"{name} ({type(exc).__name__}: {' '.join(str(exc).split())[:120]})")
    raise RenderError(
        f"no usable OpenGL backend for rendering; tried MUJOCO_GL = {'; '.join(tried)}. "
        f"Install EGL (Debian: libegl1 libegl-mesa0 libopengl0 libgl1-mesa-dri) or OSMesa "
        f"(libosmesa6), or set MUJOCO_GL to a backend this machine has")


def framing_camera(model: Any) -> Any:
    """A free camera looking at the first joint's anchor from the side (perpendicular to the
    hinges of the planar mechanisms), far enough that every moving geom stays in view
    whatever the joint angles: the reach ``R`` (largest distance of a moving geom's bounding
    sphere from the anchor at ``qpos0``) fills about 80 % of the half-height at 45 degrees of
    field of view."""
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    root = np.array(d.xanchor[0] if model.njnt else model.stat.center, dtype=float)
    moving = [g for g in range(model.ngeom) if model.geom_bodyid[g] > 0]
    reach = max((float(np.linalg.norm(d.geom_xpos[g] - root)) + float(model.geom_rbound[g])
                 for g in moving), default=float(model.stat.extent))
    cam = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, cam)
    cam.lookat[:] = root
    cam.distance = 2.6 * reach
    cam.azimuth, cam.elevation = 90.0, -10.0
    return cam


class GhostRenderer:
    """Frames of a MuJoCo model with the true pose and the estimate's ghost.

    Parameters
    ----------
    model : mujoco.MjModel
        The plant's model (only read).
    qpos_adr : sequence of int
        ``qpos`` address of each joint whose position is a plant state, in state order.
    width, height : int
        Frame size in pixels (at most the model's offscreen buffer, 640 x 480 by default).

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.plants import make_plant
    >>> plant = make_plant("pendulum")
    >>> r = GhostRenderer(plant.model, [0], width=64, height=48)
    >>> r.render(np.array([0.5]), np.array([0.1])).shape
    (48, 64, 3)
    """

    def __init__(self, model: Any, qpos_adr: Sequence[int] | NDArray[np.intp], *, width: int = 480,
                 height: int = 480) -> None:
        if not isinstance(model, mujoco.MjModel):
            raise RenderError(f"model must be a mujoco.MjModel; found {type(model).__name__}")
        w = min(int(width), int(model.vis.global_.offwidth))
        h = min(int(height), int(model.vis.global_.offheight))
        model = copy.deepcopy(model)  # lit for rendering; the plant's model is not touched
        model.vis.headlight.ambient[:] = 0.4
        model.vis.headlight.diffuse[:] = 0.7
        model.vis.headlight.specular[:] = 0.2
        self.model = model
        self._adr = np.asarray(qpos_adr, dtype=np.intp)
        self._true, self._ghost = mujoco.MjData(model), mujoco.MjData(model)
        self._ctx, self.backend = gl_context()
        self._con = mujoco.MjrContext(model, int(mujoco.mjtFontScale.mjFONTSCALE_100))
        mujoco.mjr_setBuffer(int(mujoco.mjtFramebuffer.mjFB_OFFSCREEN), self._con)
        self._scene = mujoco.MjvScene(model, maxgeom=4 * max(model.ngeom, 10) + 100)
        self._opt, self._pert = mujoco.MjvOption(), mujoco.MjvPerturb()
        self.camera = framing_camera(model)
        self._rect = mujoco.MjrRect(0, 0, w, h)
        self._rgb = np.zeros((h, w, 3), dtype=np.uint8)

    def render(self, q_true: NDArray[np.float64], q_ghost: NDArray[np.float64]) -> NDArray[np.uint8]:
        """One ``(height, width, 3)`` uint8 frame: the model at the joint positions ``q_true``
        and its ghost at ``q_ghost`` (both in state order)."""
        m = self.model
        self._ctx.make_current()
        for d, q in ((self._true, q_true), (self._ghost, q_ghost)):
            d.qpos[self._adr] = q
            mujoco.mj_kinematics(m, d)
        scn = self._scene
        mujoco.mjv_updateScene(m, self._true, self._opt, self._pert, self.camera, _ALL, scn)
        n0 = scn.ngeom
        mujoco.mjv_addGeoms(m, self._ghost, self._opt, self._pert, _DYNAMIC, scn)
        for i in range(n0, scn.ngeom):
            scn.geoms[i].rgba[:] = GHOST_RGBA
        mujoco.mjr_render(self._rect, scn, self._con)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._con)
        return np.flipud(self._rgb).copy()

    def close(self) -> None:
        """Free this renderer's GPU buffers (the shared context stays)."""
        if getattr(self, "_con", None) is not None:
            self._ctx.make_current()
            self._con.free()
            self._con = None


__all__ = ["GHOST_RGBA", "GhostRenderer", "RenderError", "framing_camera", "gl_context"]
