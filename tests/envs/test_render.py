"""Rendering of every environment: the true pose and the estimate's ghost in one frame,
headless (EGL or OSMesa), deterministic; RecordVideo on top; the errors."""

from __future__ import annotations

import gymnasium as gym
import hgo_mj.envs as envs
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from hgo_mj.envs import ENVIRONMENTS


@pytest.mark.parametrize("env_id", sorted(ENVIRONMENTS))
def test_every_environment_renders_a_frame_with_its_ghost(env_id):
    env = gym.make(env_id, render_mode="rgb_array")
    assert env.metadata["render_modes"] == ["rgb_array", "human"]
    assert env.metadata["render_fps"] == round(1.0 / env.unwrapped.control_period)
    env.reset(seed=3)
    frame = env.render()
    assert frame.shape == (480, 480, 3) and frame.dtype == np.uint8
    assert frame.std() > 5.0  # not blank
    # the same seed, the same frame (a second environment: its own renderer)
    other = gym.make(env_id, render_mode="rgb_array")
    other.reset(seed=3)
    np.testing.assert_array_equal(other.render(), frame)
    env.close()
    other.close()


def test_the_ghost_shows_where_the_estimate_is_off():
    """At reset the pendulum is at 0.5 rad and the estimate at the first measurement, which a
    sensor bias of -0.5 rad puts at 0: the frame differs from one whose ghost sits at the
    truth; a ghost 1 rad off likewise, in green pixels where the true pendulum is not."""
    env = envs.PendulumSwingUpEnv(render_mode="rgb_array",
                                  sensor=[{"stage": "bias", "offset": -0.5}])
    env.reset(seed=0, options={"x0": [0.5, 0.0]})
    assert env.current_row()["x_hat"][0] != pytest.approx(0.5, abs=0.1)
    frame = env.render()
    r, q = env._renderer, np.array([0.5])
    same, off = r.render(q, q), r.render(q, q + 1.0)

    def changed(a, b):
        return int((np.abs(a.astype(int) - b).sum(-1) > 30).sum())

    assert changed(frame, same) > 500
    assert changed(off, same) > 500
    green = (off[..., 1].astype(int) - off[..., 0] > 60) & (off[..., 1] > 100)
    assert np.any(green & (np.abs(off.astype(int) - same).sum(-1) > 30))
    env.close()


def test_frames_have_a_floor_and_the_tasks_target():
    """The hanging pendulum: the frame is the renderer's with the ghost and the upright target
    (translucent yellow where the pendulum is not) over a grey floor under the lowest pose."""
    from hgo_mj.envs.render import FLOOR_RGBA, GhostRenderer, floor_height

    env = envs.PendulumSwingUpEnv(render_mode="rgb_array", observer=None, observation="true")
    env.reset(seed=0, options={"x0": [0.0, 0.0]})
    frame = env.render()
    r, q = env._renderer, np.array([0.0])
    np.testing.assert_array_equal(frame, r.render(q, q, np.array([np.pi])))
    bare = r.render(q, q)
    diff = np.abs(frame.astype(int) - bare).sum(-1) > 30
    yellow = (frame[..., 0] > 120) & (frame[..., 1] > 90) & (frame[..., 2].astype(int) <
                                                             frame[..., 1] - 40)
    assert (diff & yellow).sum() > 200  # the target, above the pivot
    rows = np.flatnonzero((diff & yellow).any(1))
    assert rows.max() < frame.shape[0] // 2
    assert r.floor == floor_height(env.plant.model) < -0.45  # below the hanging pendulum
    plain = GhostRenderer(env.plant.model, env.plant._qadr, floor=False)
    assert plain.floor is None
    no_floor = plain.render(q, q)
    bottom = bare[-40:].astype(int)  # the floor, lit: grey-blue as FLOOR_RGBA, darker
    assert (bottom.sum(-1) > 90).mean() > 0.9
    assert (np.abs(bottom[..., 2] - bottom[..., 0] - 255 * (FLOOR_RGBA[2] - FLOOR_RGBA[0]))
            < 12).mean() > 0.9
    assert (np.abs(no_floor[-40:].astype(int) - bottom).sum(-1) > 30).mean() > 0.9
    plain.close()
    env.close()


def test_render_without_a_mode_warns_and_before_reset_raises():
    env = envs.PendulumSwingUpEnv()
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert env.render() is None
    env = envs.PendulumSwingUpEnv(render_mode="rgb_array")
    with pytest.raises(ResetNeeded, match="call reset"):
        env.render()
    with pytest.raises(ResetNeeded, match=r"call reset\(\) before step\(\)"):
        env.step(np.zeros(1, dtype=np.float32))


def test_record_video_writes_an_mp4(tmp_path):
    env = gym.wrappers.RecordVideo(gym.make("hgo_mj/PendulumSwingUp-v0", render_mode="rgb_array",
                                            max_episode_steps=20),
                                   str(tmp_path), episode_trigger=lambda i: True,
                                   disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, term, trunc, _ = env.step(env.action_space.sample())
        done = term or trunc
    env.close()
    videos = list(tmp_path.glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000


def test_no_usable_backend_is_one_clear_error(monkeypatch):
    """Each backend tried in turn (MUJOCO_GL unset), each failing (here: modules that do not
    import, as on a machine without EGL, OSMesa and a display): one error naming each."""
    from hgo_mj.envs import render

    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(render, "_CONTEXT", [])
    monkeypatch.setattr(render, "_BACKENDS", {k: f"hgo_mj_no_such_gl_{k}"
                                              for k in ("egl", "osmesa", "glfw")})
    env = envs.PendulumSwingUpEnv(render_mode="rgb_array")
    env.reset(seed=0)
    with pytest.raises(render.RenderError) as err:
        env.render()
    msg = str(err.value)
    assert msg.startswith("no usable OpenGL backend for rendering; tried MUJOCO_GL = egl "
                          "(ModuleNotFoundError"), msg
    assert "; osmesa (" in msg and "; glfw (" in msg and "libegl1" in msg
    monkeypatch.setenv("MUJOCO_GL", "wgl")
    with pytest.raises(render.RenderError, match=r"tried MUJOCO_GL = wgl \(not one of "):
        env.render()


@pytest.mark.parametrize("mujoco_gl,binding", [(None, "OpenGL"), ("osmesa", "OpenGL"),
                                               ("glfw", "glfw")])
def test_rendering_without_the_render_extra_is_one_line_naming_it(monkeypatch, mujoco_gl,
                                                                  binding):
    """The runtime install has mujoco-core without its Python OpenGL bindings (PyOpenGL,
    glfw): a render mode stops at gym.make, before any work, and a renderer made directly
    (the wrapper's) before any backend is tried, with one line naming the render extra."""
    import sys

    from hgo_mj.envs import render

    from hgo_mj.exceptions import MissingExtraError

    if mujoco_gl is None:
        monkeypatch.delenv("MUJOCO_GL", raising=False)
    else:
        monkeypatch.setenv("MUJOCO_GL", mujoco_gl)
    monkeypatch.setitem(sys.modules, binding, None)  # `import OpenGL` raises ImportError
    monkeypatch.setattr(render, "_CONTEXT", [])  # no context made yet in this process
    line = (f'render_mode="rgb_array" needs the optional dependency {binding}: '
            f"pip install 'hgo_mj[render]'")
    with pytest.raises(MissingExtraError) as err:
        gym.make("hgo_mj/PendulumSwingUp-v0", render_mode="rgb_array")
    assert str(err.value) == line and err.value.extra == "render"
    with pytest.raises(MissingExtraError) as err:
        gym.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=2,
                     vectorization_mode="vector_entry_point", render_mode="rgb_array")
    assert str(err.value) == line
    env = envs.PendulumSwingUpEnv()
    with pytest.raises(MissingExtraError) as err:
        render.GhostRenderer(env.plant.model, env.plant._qadr)
    assert str(err.value) == line
    assert not render._CONTEXT
    monkeypatch.setitem(sys.modules, "glfw", None)
    with pytest.raises(MissingExtraError, match=r'^render_mode="human" needs the optional '
                                                r"dependency glfw: pip install 'hgo_mj\[render\]'$"):
        gym.make("hgo_mj/PendulumSwingUp-v0", render_mode="human")


def test_the_native_vector_environment_renders_each_member_as_the_single_one():
    """make_vec(..., render_mode="rgb_array"): one frame per member, each equal to the single
    environment's frame at the same seed after the same actions; the errors as the single's."""
    N = 2
    venv = gym.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=N,
                        vectorization_mode="vector_entry_point", render_mode="rgb_array")
    assert venv.metadata["render_modes"] == ["rgb_array"] and venv.render_mode == "rgb_array"
    with pytest.raises(ResetNeeded, match="call reset"):
        venv.render()
    venv.reset(seed=[5, 6])
    actions = np.full((N, 1), 0.4, dtype=np.float32)
    for _ in range(3):
        venv.step(actions)
    frames = venv.render()
    assert len(frames) == N and all(f.shape == (480, 480, 3) for f in frames)
    for i, seed in enumerate([5, 6]):
        single = gym.make("hgo_mj/PendulumSwingUp-v0", render_mode="rgb_array")
        single.reset(seed=seed)
        for _ in range(3):
            single.step(actions[i])
        np.testing.assert_array_equal(single.render(), frames[i])
    plain = gym.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=N,
                         vectorization_mode="vector_entry_point")
    plain.reset(seed=0)
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert plain.render() is None


HUMAN = """
import time
import gymnasium as gym
import numpy as np
import hgo_mj.envs
from gymnasium.utils.env_checker import check_env
from hgo_mj.envs.render import HumanViewer

# Gymnasium's checker makes the environment in each declared render mode (human included)
check_env(gym.make("hgo_mj/ElasticJointReach-v0", render_mode="rgb_array").unwrapped,
          skip_render_check=False)

env = gym.make("hgo_mj/PendulumSwingUp-v0", render_mode="human")
obs, info = env.reset(seed=0)
viewer = env.unwrapped._renderer
assert isinstance(viewer, HumanViewer) and viewer.is_running
t0 = time.monotonic()
for _ in range(20):
    obs, *_ = env.step(np.ones(1, dtype=np.float32))
    assert env.render() is None
elapsed = time.monotonic() - t0
fps = env.metadata["render_fps"]
ghost = viewer.viewer.user_scn.ngeom
env.close()
print(ghost, elapsed >= 19 / fps, viewer.viewer is None)
"""


def test_human_mode_shows_the_viewer_with_the_ghost_on_a_display(tmp_path):
    """Under a virtual display (xvfb-run, installed by `make test`): Gymnasium's checker passes
    with rendering in every declared mode; MuJoCo's viewer opens at reset, reset and step draw
    (render() returns None) at render_fps, the ghost is in its user scene, close() closes the
    window."""
    import shutil
    import subprocess
    import sys

    xvfb = shutil.which("xvfb-run")
    assert xvfb, ("xvfb-run is missing: install Debian's xvfb and xauth (scripts/system_deps.sh, "
                  "run by make test)")
    (tmp_path / "human.py").write_text(HUMAN)
    out = subprocess.run([xvfb, "-a", "-s", "-screen 0 800x600x24", sys.executable,
                          str(tmp_path / "human.py")], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    ghost, paced, closed = out.stdout.split()[-3:]
    assert int(ghost) > 0 and paced == "True" and closed == "True", out.stdout


def test_human_mode_without_a_display_is_one_clear_error(monkeypatch):
    from hgo_mj.envs.render import RenderError

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RenderError, match='render_mode="human" opens a window, and there is no '
                                          'display: DISPLAY and WAYLAND_DISPLAY are unset. Use '
                                          'render_mode="rgb_array"'):
        gym.make("hgo_mj/PendulumSwingUp-v0", render_mode="human")
    from hgo_mj.exceptions import DesignError

    with pytest.raises(DesignError, match="render_mode must be None or 'rgb_array'; found "
                                          "'human'"):
        gym.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=2,
                     vectorization_mode="vector_entry_point", render_mode="human")


@pytest.mark.parametrize("env_id,joints", [
    ("Hopper-v5", ["rootz", "rooty", "thigh_joint", "leg_joint", "foot_joint"]),
    ("InvertedDoublePendulum-v5", ["slider", "hinge", "hinge2"]),
])
def test_the_wrapper_renders_a_gymnasium_mujoco_environment_with_the_ghost(env_id, joints):
    from hgo_mj.envs.wrappers import ObserverInTheLoop

    def make():
        return ObserverInTheLoop(gym.make(env_id, render_mode="rgb_array"), joints=joints,
                                 sensor=[{"stage": "gaussian", "std": 1e-3}])

    env = make()
    with pytest.raises(ResetNeeded, match=r"call reset\(\) before render\(\)"):
        env.render()
    env.reset(seed=2)
    for _ in range(5):
        env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    frame = env.render()
    assert frame.shape == (480, 480, 3) and frame.dtype == np.uint8 and frame.std() > 5.0
    other = make()
    other.reset(seed=2)
    for _ in range(5):
        other.step(np.zeros(env.action_space.shape, dtype=np.float32))
    np.testing.assert_array_equal(other.render(), frame)  # the same seed, the same frame
    # an estimate far off: its ghost shows
    x = np.array(env.observer.x_hat, dtype=float)
    x[:len(joints)] += 0.6
    env.observer.reset(x_hat0=x)
    off = env.render()
    assert np.abs(off.astype(int) - frame.astype(int)).max() > 60
    env.close()
    other.close()


def test_two_renderers_interleaved_each_draw_their_own_frame():
    """Each renderer binds its own offscreen buffer at every frame (a second renderer once
    made the first read the second's frames)."""
    a = gym.make("hgo_mj/PendulumSwingUp-v0", render_mode="rgb_array")
    b = gym.make("hgo_mj/PendulumSwingUp-v0", render_mode="rgb_array")
    a.reset(seed=0, options={"x0": [0.3, 0.0]})
    first = a.render()
    b.reset(seed=0, options={"x0": [2.5, 0.0]})
    other = b.render()
    assert np.abs(other.astype(int) - first.astype(int)).max() > 60
    np.testing.assert_array_equal(a.render(), first)
    a.close()
    b.close()


@pytest.mark.parametrize("backend", ["osmesa", "glfw", "bogus"])
def test_a_named_backend_this_machine_lacks_is_a_render_error(backend):
    """Issue 27 item 13: MUJOCO_GL naming a backend that is missing or cannot draw gives the
    documented RenderError (or a frame where the backend works), never MuJoCo's FatalError."""
    import os
    import subprocess
    import sys

    code = ("import gymnasium as gym, hgo_mj.envs\n"
            "from hgo_mj.envs.render import RenderError\n"
            "env = gym.make('hgo_mj/PendulumSwingUp-v0', render_mode='rgb_array')\n"
            "env.reset(seed=0)\n"
            "try:\n    frame = env.render()\n    print('FRAME', frame.shape)\n"
            "except RenderError as exc:\n    print('RENDERERROR', exc)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, env={**os.environ, "MUJOCO_GL": backend})
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith(("FRAME", "RENDERERROR")), res.stdout
    if backend == "bogus":
        assert "not one of ['egl', 'glfw', 'osmesa']" in res.stdout
