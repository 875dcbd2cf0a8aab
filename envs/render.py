"""Headless rendering of an environment: the true pose and, in the same frame, a translucent
ghost posed from the observer's estimate.

:class:`GhostRenderer` draws with MuJoCo's own renderer (``mjv_updateScene`` /
``mjr_render``) into an offscreen buffer. The ghost is the model's dynamic geoms added a
second time (``mjv_addGeoms``) from a copy of the data posed at the estimate, tinted and
translucent; where the estimate equals the truth it hides inside the true bodies. The free
camera frames the whole model (``mjv_defaultFreeCamera``: the model's centre and extent).

**OpenGL backend.** The backend named by ``MUJOCO_GL`` (``egl``, ``osmesa`` or ``glfw``) when
it is set; otherwise EGL, then OSMesa, then GLFW are tried in turn, so that rendering works on a
headless machine without setting anything (``make test`` installs Debian's ``libegl1``,
``libegl-mesa0``, ``libopengl0`` and ``libgl1-mesa-dri``). When none can be made,
:class:`RenderError` says which were tried, why each failed, and what to install.

**Bindings.** The backends' Python modules import PyOpenGL (EGL, OSMesa) or ``glfw`` (GLFW
and the viewer), which the runtime install leaves out (it needs only ``mujoco-core``); the
``render`` extra installs them. Without them :func:`require_render` stops rendering, before any
work, with one line naming that extra.

**On screen** (``render_mode="human"``), :class:`HumanViewer` shows the same scene in MuJoCo's
own interactive viewer (``mujoco.viewer.launch_passive``: GLFW on the X or Wayland display),
the ghost in the viewer's user scene, one frame per environment step at ``render_fps``. It
needs a display (``DISPLAY`` or ``WAYLAND_DISPLAY``; ``xvfb-run`` gives a virtual one).
"""

from __future__ import annotations

import atexit
import copy
import importlib
import os
import threading
import time
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from hgo_mj._extras import require
from hgo_mj.exceptions import HgoError

#: MUJOCO_GL value -> the mujoco module holding its GLContext
_BACKENDS = {"egl": "mujoco.egl", "osmesa": "mujoco.osmesa", "glfw": "mujoco.glfw"}
#: MUJOCO_GL value -> the Python binding its module imports (the ``render`` extra has both)
_BINDINGS = {"egl": "OpenGL", "osmesa": "OpenGL", "glfw": "glfw"}
#: the ghost's colour: a translucent green
GHOST_RGBA = (0.1, 0.9, 0.5, 0.45)
#: the task's target pose: a translucent yellow
TARGET_RGBA = (1.0, 0.8, 0.1, 0.35)
#: the floor drawn under a model without one: a grey plane
FLOOR_RGBA = (0.45, 0.45, 0.5, 1.0)
_DYNAMIC = int(mujoco.mjtCatBit.mjCAT_DYNAMIC)
_ALL = int(mujoco.mjtCatBit.mjCAT_ALL)


class RenderError(HgoError, RuntimeError):
    """No OpenGL backend could be made for rendering.

    Also raised by :class:`GhostRenderer` for a model that is not a ``mujoco.MjModel``.
    A :class:`~hgo_mj.exceptions.HgoError` and a ``RuntimeError``.

    Examples
    --------
    >>> from hgo_mj.envs.render import GhostRenderer, RenderError
    >>> try:
    ...     GhostRenderer("pendulum.xml", [0])
    ... except RenderError as exc:
    ...     print(exc)
    model must be a mujoco.MjModel; found str
    """


def require_render(render_mode: str) -> None:
    """Raise the one-line error naming the ``render`` extra unless the Python binding that
    ``render_mode`` first needs is installed: ``glfw`` for ``"human"`` (MuJoCo's viewer); for
    ``"rgb_array"`` the binding of the backend ``MUJOCO_GL`` names, else of EGL, the first
    one tried (PyOpenGL).

    Parameters
    ----------
    render_mode : {"rgb_array", "human"}
        The environment's render mode.

    Raises
    ------
    hgo_mj.exceptions.MissingExtraError
        The binding is not installed (an ``ImportError``): ``pip install 'hgo_mj[render]'``.

    Examples
    --------
    >>> import sys
    >>> from hgo_mj.envs.render import require_render
    >>> saved = sys.modules.get("glfw")
    >>> sys.modules["glfw"] = None  # as if glfw were not installed
    >>> try:
    ...     require_render("human")
    ... except ImportError as exc:
    ...     print(exc)
    render_mode="human" needs the optional dependency glfw: pip install 'hgo_mj[render]'
    >>> if saved is None:
    ...     del sys.modules["glfw"]
    ... else:
    ...     sys.modules["glfw"] = saved
    """
    backend = "glfw" if render_mode == "human" else (
        os.environ.get("MUJOCO_GL", "").strip().lower() or "egl")
    if backend in _BINDINGS:  # another name: gl_context says it is not a backend
        require(_BINDINGS[backend], "render", f'render_mode="{render_mode}"')


#: the process's one OpenGL context and its backend (made on first use, never freed: freeing
#: an EGL context tore down the display under the others, whose frames then came out black)
_CONTEXT: list[tuple[Any, str]] = []


def gl_context() -> tuple[Any, str]:
    """The process's offscreen OpenGL context, made current, and its backend's name. Every
    renderer draws into its own offscreen framebuffer (``mjr_setBuffer``) in this context.

    Returns
    -------
    context : mujoco.egl.GLContext, mujoco.osmesa.GLContext or mujoco.glfw.GLContext
        The context, current on the calling thread; made once per process, never freed.
    backend : {"egl", "osmesa", "glfw"}
        The backend that made it.

    Raises
    ------
    RenderError
        No backend could be made: the message lists each one tried with its error.
    hgo_mj.exceptions.MissingExtraError
        The ``render`` extra is not installed (:func:`require_render`).

    Examples
    --------
    Skipped here: it needs an OpenGL backend.

    >>> from hgo_mj.envs.render import gl_context
    >>> ctx, backend = gl_context()  # doctest: +SKIP
    >>> backend  # doctest: +SKIP
    'egl'
    """
    if _CONTEXT:
        _CONTEXT[0][0].make_current()
        return _CONTEXT[0]
    require_render("rgb_array")
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


def _reach(model: Any) -> tuple[NDArray[np.float64], float]:
    """The first joint's anchor (the model's centre without joints) and the reach ``R``: the
    largest distance of a moving geom's bounding sphere from it at ``qpos0``."""
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    root = np.array(d.xanchor[0] if model.njnt else model.stat.center, dtype=float)
    moving = [g for g in range(model.ngeom) if model.geom_bodyid[g] > 0]
    reach = max((float(np.linalg.norm(d.geom_xpos[g] - root)) + float(model.geom_rbound[g])
                 for g in moving), default=float(model.stat.extent))
    return root, reach


def floor_height(model: Any) -> float | None:
    """Height [m] of the floor drawn under ``model``: the reach ``R`` (see
    :func:`framing_camera`) below the first joint's anchor, 5 % lower, so that no pose goes
    through it; None for a model that has a plane of its own.

    Parameters
    ----------
    model : mujoco.MjModel
        The model (only read).

    Returns
    -------
    float or None

    Examples
    --------
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.envs.render import floor_height
    >>> round(floor_height(make_plant("pendulum").model), 3)
    -0.551
    """
    if np.any(model.geom_type == int(mujoco.mjtGeom.mjGEOM_PLANE)):
        return None
    root, reach = _reach(model)
    return float(root[2] - 1.05 * reach)


def framing_camera(model: Any) -> Any:
    """A free camera looking at the first joint's anchor from the side (perpendicular to the
    hinges of the planar mechanisms), far enough that every moving geom stays in view
    whatever the joint angles: the reach ``R`` (largest distance of a moving geom's bounding
    sphere from the anchor at ``qpos0``) fills about 80 % of the half-height at 45 degrees of
    field of view.

    Parameters
    ----------
    model : mujoco.MjModel
        The model to frame (only read).

    Returns
    -------
    mujoco.MjvCamera
        A free camera: ``lookat`` the first joint's anchor (the model's centre without
        joints), ``distance`` 2.6 times the reach [m], azimuth 90 and elevation -10 degrees.

    Examples
    --------
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.envs.render import framing_camera
    >>> cam = framing_camera(make_plant("pendulum").model)
    >>> cam.lookat.tolist(), round(cam.distance, 3), cam.azimuth, cam.elevation
    ([0.0, 0.0, 0.0], 1.365, 90.0, -10.0)
    """
    root, reach = _reach(model)
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
    floor : bool, default True
        Draw a grey floor (:data:`FLOOR_RGBA`) at :func:`floor_height` under a model without
        a plane of its own.

    Raises
    ------
    RenderError
        ``model`` is not a ``mujoco.MjModel``, or no OpenGL backend could be made
        (:func:`gl_context`).

    Examples
    --------
    Rendering needs an OpenGL backend, so the lines that make the renderer are skipped here.

    >>> import numpy as np
    >>> from hgo_mj.plants import make_plant
    >>> plant = make_plant("pendulum")
    >>> r = GhostRenderer(plant.model, [0], width=64, height=48)  # doctest: +SKIP
    >>> r.render(np.array([0.5]), np.array([0.1])).shape  # doctest: +SKIP
    (48, 64, 3)
    """

    def __init__(self, model: Any, qpos_adr: Sequence[int] | NDArray[np.intp], *, width: int = 480,
                 height: int = 480, floor: bool = True) -> None:
        if not isinstance(model, mujoco.MjModel):
            raise RenderError(f"model must be a mujoco.MjModel; found {type(model).__name__}")
        #: height of the drawn floor [m] (None: none drawn)
        self.floor = floor_height(model) if floor else None
        w = min(int(width), int(model.vis.global_.offwidth))
        h = min(int(height), int(model.vis.global_.offheight))
        model = copy.deepcopy(model)  # lit for rendering; the plant's model is not touched
        model.vis.headlight.ambient[:] = 0.4
        model.vis.headlight.diffuse[:] = 0.7
        model.vis.headlight.specular[:] = 0.2
        self.model = model
        self._adr = np.asarray(qpos_adr, dtype=np.intp)
        self._true, self._ghost = mujoco.MjData(model), mujoco.MjData(model)
        self._target = mujoco.MjData(model)
        self._floor_size = 3.0 * _reach(model)[1]
        self._ctx, self.backend = gl_context()
        try:
            self._con = mujoco.MjrContext(model, int(mujoco.mjtFontScale.mjFONTSCALE_100))
        except Exception as exc:  # noqa: BLE001 - a context made without a usable GL (glfw)
            raise RenderError(f"the OpenGL backend MUJOCO_GL = {self.backend} made a context "
                              f"MuJoCo cannot draw with ({type(exc).__name__}: "
                              f"{' '.join(str(exc).split())[:160]}). Install EGL (Debian: "
                              f"libegl1 libegl-mesa0 libopengl0 libgl1-mesa-dri) or OSMesa "
                              f"(libosmesa6), or set MUJOCO_GL to a backend this machine has"
                              ) from None
        mujoco.mjr_setBuffer(int(mujoco.mjtFramebuffer.mjFB_OFFSCREEN), self._con)
        self._scene = mujoco.MjvScene(model, maxgeom=4 * max(model.ngeom, 10) + 100)
        self._opt, self._pert = mujoco.MjvOption(), mujoco.MjvPerturb()
        self.camera = framing_camera(model)
        self._rect = mujoco.MjrRect(0, 0, w, h)
        self._rgb = np.zeros((h, w, 3), dtype=np.uint8)

    def render(self, q_true: NDArray[np.float64], q_ghost: NDArray[np.float64],
               q_target: NDArray[np.float64] | None = None) -> NDArray[np.uint8]:
        """One ``(height, width, 3)`` uint8 frame: the model at the joint positions ``q_true``,
        its ghost at ``q_ghost`` and the task's target pose at ``q_target`` (all in state
        order), over the floor.

        Parameters
        ----------
        q_true : (k,) array
            True joint positions, one per ``qpos_adr`` entry [rad or m].
        q_ghost : (k,) array
            Joint positions of the ghost (the estimate), the same layout.
        q_target : (k,) array, optional
            Joint positions of the task's target, drawn translucent yellow
            (:data:`TARGET_RGBA`); None: no target drawn.

        Returns
        -------
        (height, width, 3) uint8 array
            The frame, a new array, top row first.

        Examples
        --------
        Skipped here: it needs an OpenGL backend.

        >>> import numpy as np
        >>> from hgo_mj.plants import make_plant
        >>> r = GhostRenderer(make_plant("pendulum").model, [0])  # doctest: +SKIP
        >>> frame = r.render(np.array([3.0]), np.array([2.8]))  # doctest: +SKIP
        >>> frame.shape, frame.dtype  # doctest: +SKIP
        ((480, 480, 3), dtype('uint8'))
        """
        m = self.model
        self._ctx.make_current()
        # every renderer has its own offscreen buffer: bind this one (another renderer made
        # since bound its own, and this one's frames were read from it)
        mujoco.mjr_setBuffer(int(mujoco.mjtFramebuffer.mjFB_OFFSCREEN), self._con)
        posed = [(self._true, q_true), (self._ghost, q_ghost)]
        if q_target is not None:
            posed.append((self._target, q_target))
        for d, q in posed:
            d.qpos[self._adr] = q
            mujoco.mj_kinematics(m, d)
        scn = self._scene
        mujoco.mjv_updateScene(m, self._true, self._opt, self._pert, self.camera, _ALL, scn)
        for d, rgba in ((self._ghost, GHOST_RGBA), (self._target, TARGET_RGBA))[:len(posed) - 1]:
            n0 = scn.ngeom
            mujoco.mjv_addGeoms(m, d, self._opt, self._pert, _DYNAMIC, scn)
            for i in range(n0, scn.ngeom):
                scn.geoms[i].rgba[:] = rgba
        if self.floor is not None and scn.ngeom < scn.maxgeom:
            c = self.camera.lookat
            mujoco.mjv_initGeom(scn.geoms[scn.ngeom], int(mujoco.mjtGeom.mjGEOM_PLANE),
                                np.array([self._floor_size, self._floor_size, 0.1]),
                                np.array([c[0], c[1], self.floor]), np.eye(3).ravel(),
                                np.array(FLOOR_RGBA, dtype=np.float32))
            scn.ngeom += 1
        mujoco.mjr_render(self._rect, scn, self._con)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._con)
        return np.flipud(self._rgb).copy()

    def close(self) -> None:
        """Free this renderer's GPU buffers (the shared context stays).

        Idempotent; the renderer cannot render afterwards.

        Examples
        --------
        Skipped here: it needs an OpenGL backend.

        >>> from hgo_mj.plants import make_plant
        >>> r = GhostRenderer(make_plant("pendulum").model, [0])  # doctest: +SKIP
        >>> r.close()  # doctest: +SKIP
        >>> r.close()  # doctest: +SKIP
        """
        if getattr(self, "_con", None) is not None:
            self._ctx.make_current()
            self._con.free()
            self._con = None




def check_display() -> None:
    """Raise :class:`RenderError` unless a display is named (``DISPLAY`` or
    ``WAYLAND_DISPLAY``): ``render_mode="human"`` opens a window on it.

    Raises
    ------
    RenderError
        Neither variable is set.

    Examples
    --------
    >>> import os
    >>> saved = {k: os.environ.pop(k) for k in ("DISPLAY", "WAYLAND_DISPLAY") if k in os.environ}
    >>> try:
    ...     check_display()
    ... except RenderError as exc:
    ...     print(str(exc)[:62])
    render_mode="human" opens a window, and there is no display: D
    >>> os.environ.update(saved)
    """
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RenderError('render_mode="human" opens a window, and there is no display: DISPLAY '
                          'and WAYLAND_DISPLAY are unset. Use render_mode="rgb_array" (frames '
                          'as arrays; gymnasium.wrappers.RecordVideo writes them to a video), '
                          'or run under a virtual display (xvfb-run, Debian package xvfb)')


class HumanViewer:
    """MuJoCo's interactive viewer showing the true pose and the estimate's ghost
    (``render_mode="human"``), paced at ``fps`` frames per second of wall time.

    Parameters
    ----------
    model : mujoco.MjModel
        The plant's model (only read; the viewer shows a copy).
    qpos_adr : sequence of int
        ``qpos`` address of each joint whose position is a plant state, in state order.
    fps : float
        Frames per second: :meth:`show` waits so that frames are ``1 / fps`` apart.

    Raises
    ------
    RenderError
        No display (:func:`check_display`), or the viewer's window could not be opened.
    hgo_mj.exceptions.MissingExtraError
        The ``render`` extra is not installed (:func:`require_render`).

    Examples
    --------
    Skipped here: it needs a display (tests/envs/test_render.py runs it under xvfb-run).

    >>> import numpy as np
    >>> from hgo_mj.plants import make_plant
    >>> viewer = HumanViewer(make_plant("pendulum").model, [0], fps=50)  # doctest: +SKIP
    >>> viewer.show(np.array([3.0]), np.array([2.8]))  # doctest: +SKIP
    >>> viewer.close()  # doctest: +SKIP
    """

    def __init__(self, model: Any, qpos_adr: Sequence[int] | NDArray[np.intp], *,
                 fps: float) -> None:
        require_render("human")
        check_display()
        import mujoco.viewer

        self.model = copy.deepcopy(model)
        self._adr = np.asarray(qpos_adr, dtype=np.intp)
        self._true, self._ghost = mujoco.MjData(self.model), mujoco.MjData(self.model)
        self._opt, self._pert = mujoco.MjvOption(), mujoco.MjvPerturb()
        before = set(threading.enumerate())
        try:
            self.viewer = mujoco.viewer.launch_passive(self.model, self._true,
                                                       show_left_ui=False, show_right_ui=False)
        except Exception as exc:  # GLFW: no usable display or GL
            raise RenderError(f'render_mode="human": the viewer could not open a window on '
                              f'{os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")!r}'
                              f': {exc}') from None
        # the viewer's thread: close() waits for it to free its window before the model and
        # data it draws are freed (a daemon thread still drawing them crashed the process)
        self._threads = [t for t in threading.enumerate() if t not in before]
        atexit.register(self.close)  # a process ending with the window open: close it first
        cam, view = framing_camera(self.model), self.viewer.cam
        view.lookat[:], view.distance = cam.lookat, cam.distance
        view.azimuth, view.elevation = cam.azimuth, cam.elevation
        self.period, self._last = 1.0 / float(fps), 0.0

    @property
    def is_running(self) -> bool:
        """Whether the window is open (the user may close it).

        Examples
        --------
        Skipped here: it needs a display.

        >>> from hgo_mj.plants import make_plant
        >>> HumanViewer(make_plant("pendulum").model, [0], fps=50).is_running  # doctest: +SKIP
        True
        """
        return self.viewer is not None and self.viewer.is_running()

    def show(self, q_true: NDArray[np.float64], q_ghost: NDArray[np.float64]) -> None:
        """Show the model at ``q_true`` and its ghost at ``q_ghost`` (a closed window stays
        closed: nothing is shown).

        Parameters
        ----------
        q_true : (k,) array
            True joint positions, one per ``qpos_adr`` entry.
        q_ghost : (k,) array
            Joint positions of the ghost (the estimate).

        Examples
        --------
        Skipped here: it needs a display.

        >>> import numpy as np
        >>> from hgo_mj.plants import make_plant
        >>> viewer = HumanViewer(make_plant("pendulum").model, [0], fps=50)  # doctest: +SKIP
        >>> viewer.show(np.array([3.0]), np.array([2.8]))  # doctest: +SKIP
        """
        if not self.is_running:
            return
        m, v = self.model, self.viewer
        with v.lock():
            for d, q in ((self._true, q_true), (self._ghost, q_ghost)):
                d.qpos[self._adr] = q
                mujoco.mj_kinematics(m, d)
            scn = v.user_scn
            scn.ngeom = 0
            mujoco.mjv_addGeoms(m, self._ghost, self._opt, self._pert, _DYNAMIC, scn)
            for i in range(scn.ngeom):
                scn.geoms[i].rgba[:] = GHOST_RGBA
        wait = self._last + self.period - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        v.sync()
        self._last = time.monotonic()

    def close(self) -> None:
        """Close the window (idempotent).

        Examples
        --------
        Skipped here: it needs a display.

        >>> from hgo_mj.plants import make_plant
        >>> HumanViewer(make_plant("pendulum").model, [0], fps=50).close()  # doctest: +SKIP
        """
        if self.viewer is not None:
            self.viewer.close()
            for t in self._threads:
                t.join(timeout=10.0)
            self.viewer = None
            atexit.unregister(self.close)


__all__ = ["FLOOR_RGBA", "GHOST_RGBA", "TARGET_RGBA", "GhostRenderer", "HumanViewer",
           "RenderError", "check_display", "floor_height", "framing_camera", "gl_context",
           "require_render"]
