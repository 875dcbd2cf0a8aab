"""The plants' batched contract: ``reset(x0, batch=)`` and ``run(U, steps) -> (X, Yc)``.

Every member of a batch equals the same member run alone, bit for bit, and equals the
``step()``-based loop (state and outputs read at each sample, then ``steps`` calls of
``step``, i.e. blocks of one sample of one plant step through the unbatched plant's own path:
the Python ``mj_step`` loop, the per-member ``dynamics``); blocks may be cut anywhere; bad
inputs and MuJoCo's bad-state reset raise :class:`DivergenceError` naming the member and the
time.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.plants import MujocoPlant, OdePlant, make_plant, model_path
from hgo_mj.plants import mujoco as mj_plant
from hgo_mj.systems import BioreactorBullinger, JoSonExample, Pendulum

B = 64


def step_loop(plant, x0, U, steps):
    """Record state and outputs, then ``steps`` calls of ``step`` (one-sample runs)."""
    plant.reset(x0)
    X, Y = [], []
    for u in U:
        X.append(plant.state)
        Y.append(plant.outputs())
        for _ in range(steps):
            plant.step(u)
    return np.array(X), np.array(Y), plant.state, plant.t


def members(n, m, T, seed, scale_x=0.3, scale_u=1.0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((B, n)) * scale_x, rng.standard_normal((B, T, m)) * scale_u


@pytest.mark.parametrize("name, dt, steps, T", [
    ("pendulum", 0.001, 1, 200),          # one physics step per sample
    ("pendulum", 0.002, 3, 200),          # 6 physics steps per sample
    ("elastic_joint_2link", 0.002, 2, 200),
    ("cart_pendulum", 0.001, 5, 60),
])
def test_mujoco_batch_equals_single_and_the_step_loop(name, dt, steps, T):
    plant = make_plant(name, dt)
    n, m = len(plant.state_names), len(plant.input_names)
    X0, U = members(n, m, T, seed=hash(name) % 1000)
    X0 += np.array(plant.system.default_x0)
    plant.reset(X0)
    assert plant.batch == B and plant.batched and plant.state.shape == (B, n)
    X, Yc = plant.run(U, steps)
    assert X.shape == (B, T, n) and Yc.shape == (B, T, len(plant.output_names))
    t_end = plant.t
    alone = make_plant(name, dt)
    ref = make_plant(name, dt)
    for b in range(B):
        Xr, Yr, xe, te = step_loop(ref, X0[b], U[b], steps)
        np.testing.assert_array_equal(X[b], Xr)
        np.testing.assert_array_equal(Yc[b], Yr)
        np.testing.assert_array_equal(plant.state[b], xe)
        assert t_end == te
        alone.reset(X0[b])                       # B = 1, unbatched: the same bits
        X1, Y1 = alone.run(U[b:b + 1], steps)
        np.testing.assert_array_equal(X1[0], Xr)
        np.testing.assert_array_equal(Y1[0], Yr)
        np.testing.assert_array_equal(alone.state, xe)
        assert alone.t == te
        if b >= 4:   # the step loop for all 64; the single runs for a few suffice
            continue


@pytest.mark.parametrize("B_", [1, 5])
@pytest.mark.parametrize("cuts", [(1,) * 30, (7, 7, 7, 9), (30,), (2, 28)])
def test_mujoco_blocks_cut_anywhere(B_, cuts):
    """The Python loop (short single blocks) and the rollout (long or batched blocks) join
    without a seam."""
    plant = make_plant("pendulum", 0.002)
    rng = np.random.default_rng(3)
    X0 = rng.standard_normal((B_, 2)) * 0.3
    U = rng.standard_normal((B_, 30, 1))
    plant.reset(X0)
    whole = plant.run(U, 8)
    state = plant.state
    plant.reset(X0)
    parts, j = [], 0
    for c in cuts:
        parts.append(plant.run(U[:, j:j + c], 8))
        j += c
    np.testing.assert_array_equal(np.concatenate([p[0] for p in parts], axis=1), whole[0])
    np.testing.assert_array_equal(np.concatenate([p[1] for p in parts], axis=1), whole[1])
    np.testing.assert_array_equal(plant.state, state)


def test_mujoco_rollout_path_is_taken_and_chunked(monkeypatch):
    """Force small chunks: the chunked rollout gives the same bits as one chunk."""
    plant = make_plant("elastic_joint", 0.002)
    X0, U = members(4, 1, 50, seed=9)
    plant.reset(X0[:8])
    whole = plant.run(U[:8], 2)
    calls = []
    orig = MujocoPlant._run_rollout

    def spy(self, *a, **k):
        calls.append(1)
        return orig(self, *a, **k)

    monkeypatch.setattr(MujocoPlant, "_run_rollout", spy)
    monkeypatch.setattr(mj_plant, "_CHUNK_DOUBLES", 8 * 2 * 2 * 20 * 7)  # 7 samples a chunk
    plant.reset(X0[:8])
    chunked = plant.run(U[:8], 2)
    assert calls
    np.testing.assert_array_equal(chunked[0], whole[0])
    np.testing.assert_array_equal(chunked[1], whole[1])


def test_mujoco_plain_reset_stays_unbatched():
    plant = make_plant("pendulum")
    plant.reset([0.1, 0.0])
    assert plant.batch == 1 and not plant.batched and plant.state.shape == (2,)
    p = len(plant.output_names)
    assert plant.outputs().shape == (p,)
    plant.reset([0.1, 0.0], batch=1)
    assert plant.batched and plant.state.shape == (1, 2) and plant.outputs().shape == (1, p)
    plant.reset(batch=3)
    np.testing.assert_array_equal(plant.state, np.tile(Pendulum.default_x0, (3, 1)))
    plant.step(np.full((3, 1), 0.5))             # a batched step: (B, m)
    assert plant.t == pytest.approx(0.001)
    ref = make_plant("pendulum")
    ref.step([0.5])
    np.testing.assert_array_equal(plant.state, np.tile(ref.state, (3, 1)))
    np.testing.assert_array_equal(plant.outputs(), np.tile(ref.outputs(), (3, 1)))


MJCF_EXTRA = """
  <sensor>
    <framepos name="tip" objtype="site" objname="tip"/>
    <actuatorfrc name="motor_force" actuator="torque"/>
    <accelerometer name="tip_acc" site="tip"/>
  </sensor>
</mujoco>"""


@pytest.fixture
def pendulum_more_sensors(tmp_path):
    """The shipped pendulum plus position-stage (framepos) and acceleration-stage
    (actuatorfrc, accelerometer) sensors, which read ``sensordata``."""
    xml = model_path("pendulum.xml").read_text()
    xml = xml.replace('<geom name="bob"', '<site name="tip" pos="0 0 -0.5"/>\n      <geom name="bob"')
    xml = xml.replace("</mujoco>", MJCF_EXTRA.replace("</mujoco>", "", 1), 1) + "</mujoco>"
    path = tmp_path / "pendulum_sensors.xml"
    path.write_text(xml)
    return path


def test_mujoco_sensordata_outputs_batch_equals_step_loop(pendulum_more_sensors):
    outs = ("angle", "tip", "motor_force", "tip_acc", "angular_velocity")
    plant = MujocoPlant(Pendulum, 0.002, model_file=pendulum_more_sensors, outputs=outs)
    assert [k for k, _ in plant._batch_src] == ["state", "sensor", "acc", "acc", "state"]
    X0, U = members(2, 1, 40, seed=4)
    plant.reset(X0[:6])
    X, Yc = plant.run(U[:6], 3)
    ref = MujocoPlant(Pendulum, 0.002, model_file=pendulum_more_sensors, outputs=outs)
    for b in range(6):
        Xr, Yr, _, _ = step_loop(ref, X0[b], U[b], 3)
        np.testing.assert_array_equal(X[b], Xr)
        np.testing.assert_array_equal(Yc[b], Yr)
    # the actuator force at a sample is the control held before it (0 at the start)
    np.testing.assert_array_equal(Yc[:, 1:, 2], U[:6, :-1, 0])
    assert np.all(Yc[:, 0, 2] == 0.0)


def test_constraint_free_models():
    for name in ("pendulum", "cart_pendulum", "elastic_joint", "elastic_joint_2link"):
        assert mj_plant._constraint_free(make_plant(name).model), name
    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint name="j" range="-1 1"/><geom size="0.1"/></body>'
        '</worldbody></mujoco>')
    assert not mj_plant._constraint_free(m)


def test_mujoco_model_with_limits_uses_the_loop(tmp_path, monkeypatch):
    """A model that can hold constraints needs the warm start across steps: the members go
    through the mj_step loop (the rollout is not called), bit-identical to the step loop."""
    xml = model_path("pendulum.xml").read_text().replace(
        'axis="0 1 0" damping="0.01"', 'axis="0 1 0" damping="0.01" range="-0.3 0.3"')
    path = tmp_path / "limited.xml"
    path.write_text(xml)
    plant = MujocoPlant(Pendulum, 0.002, model_file=path)
    assert not plant._rollout_ok
    monkeypatch.setattr(MujocoPlant, "_run_rollout", None)  # would fail if called
    X0, U = members(2, 1, 100, seed=6, scale_u=3.0)
    plant.reset(X0[:5] * 0.5)
    X, Yc = plant.run(U[:5], 2)
    ref = MujocoPlant(Pendulum, 0.002, model_file=path)
    for b in range(5):
        Xr, Yr, xe, _ = step_loop(ref, X0[b] * 0.5, U[b], 2)
        np.testing.assert_array_equal(X[b], Xr)
        np.testing.assert_array_equal(Yc[b], Yr)
        np.testing.assert_array_equal(plant.state[b], xe)
    assert np.max(np.abs(X[:, :, 0])) > 0.29    # the limit was reached


@pytest.mark.parametrize("B_, T", [(1, 5), (1, 300), (6, 300), (6, 1)])
def test_mujoco_huge_input_names_member_and_time(B_, T):
    plant = make_plant("pendulum", 0.002)
    plant.reset(batch=B_)
    U = np.zeros((B_, T, 1))
    j = min(3, T - 1)
    U[B_ - 1, j, 0] = 1e12
    if T - 1 > j:
        U[0, T - 1, 0] = np.nan   # later: the earliest failure is reported
    with pytest.raises(DivergenceError, match=rf"member {B_ - 1} at t={0.002 * j:g}: input u\[0\] "
                                              r"must be finite and below 1e\+10 in magnitude "
                                              r"\(MuJoCo would zero it\); found 1e\+12|"
                                              r"1000000000000.0") as info:
        plant.run(U, 1)
    e = info.value
    assert e.member == B_ - 1 and e.rows == j + 1 and e.t == pytest.approx(0.002 * j)
    assert np.all(np.isfinite(e.X[:, :e.rows])) and np.all(np.isfinite(e.Yc[:, :e.rows]))
    ref = make_plant("pendulum", 0.002)
    Xr, _, _, _ = step_loop(ref, Pendulum.default_x0, np.zeros((j + 1, 1)), 1)
    np.testing.assert_array_equal(e.X[B_ - 1, :j + 1], Xr)


@pytest.mark.parametrize("B_, T", [(1, 10), (1, 400), (5, 400)])
def test_mujoco_bad_state_reset_names_member_and_time(B_, T, capfd):
    """A velocity driven past mjMAXVAL: MuJoCo resets the member; the loop (one member, short
    block) sees the warning, the rollout a time column that resets: both raise at the same
    sample, after every member's earlier samples were recorded exactly."""
    plant = make_plant("pendulum", 0.002)
    X0 = np.zeros((B_, 2))
    X0[-1] = [0.0, 9.95e9]
    U = np.zeros((B_, T, 1))
    U[-1] = 2.5e8    # accelerates the last member past 1e10 (mjMAXVAL) in 10 samples
    plant.reset(X0, batch=B_)
    with pytest.raises(DivergenceError, match=rf"member {B_ - 1} at t=[0-9.e-]+: MuJoCo found a "
                                              r"non-finite or huge value and reset the "
                                              r"simulation \(mjWARN_BADQVEL\)") as info:
        plant.run(U, 1)
    e = info.value
    assert e.member == B_ - 1 and e.rows == 10
    ref = make_plant("pendulum", 0.002)
    with pytest.raises(DivergenceError):
        step_loop(ref, X0[-1], U[-1], 1)
    Xr, _, x_last, _ = step_loop(ref, X0[-1], U[-1, :e.rows - 1], 1)
    np.testing.assert_array_equal(e.X[-1, :e.rows - 1], Xr)
    np.testing.assert_array_equal(e.X[-1, e.rows - 1], x_last)
    assert e.t == pytest.approx(0.002 * (e.rows - 1))
    assert np.all(np.isfinite(e.X[:, :e.rows]))
    capfd.readouterr()


def test_mujoco_bad_arguments():
    plant = make_plant("pendulum")
    with pytest.raises(DimensionError, match=r"x0 has 3 rows but batch is 2"):
        plant.reset(np.zeros((3, 2)), batch=2)
    with pytest.raises(DimensionError, match=r"x0 must have shape \(B, 2\); found shape \(3, 4\)"):
        plant.reset(np.zeros((3, 4)))
    with pytest.raises(DesignError, match="batch must be a positive integer or None; found 0"):
        plant.reset(batch=0)
    with pytest.raises(DesignError, match="x0 must be finite"):
        plant.reset(np.full((2, 2), np.nan))
    plant.reset(batch=2)
    with pytest.raises(DimensionError, match=r"U must have shape \(B, T, m\) = \(2, T, 1\); "
                                             r"found shape \(3, 4, 1\)"):
        plant.run(np.zeros((3, 4, 1)), 1)
    with pytest.raises(DimensionError, match=r"found shape \(4, 1\)"):
        plant.run(np.zeros((4, 1)), 1)
    with pytest.raises(DesignError, match="steps must be a positive integer"):
        plant.run(np.zeros((2, 4, 1)), 0)
    with pytest.raises(DesignError, match="nthread must be a positive integer; found 0"):
        MujocoPlant(Pendulum, nthread=0)
    X, Yc = plant.run(np.zeros((2, 0, 1)), 1)   # an empty block: nothing happens
    assert X.shape == (2, 0, 2) and plant.t == 0.0


def test_mujoco_plant_pickles_and_runs_after(tmp_path):
    import pickle

    plant = make_plant("pendulum", 0.002, nthread=2)
    plant.reset(batch=3)
    plant.run(np.zeros((3, 50, 1)), 1)
    copy = pickle.loads(pickle.dumps(plant))
    U = np.ones((3, 40, 1))
    np.testing.assert_array_equal(copy.run(U, 1)[0], plant.run(U, 1)[0])


# ----------------------------------------------------------------------------- ODE plants
class BatchedBullinger(BioreactorBullinger):
    """Paper 000, eq. 15 written once more over rows: the same operations as ``dynamics``."""

    @staticmethod
    def dynamics_batch(t, X, U, p):
        m, s, uu = X[:, 0], X[:, 1], U[:, 0]
        g = p["a1"] * m * s / (p["a2"] * m + s)
        return np.stack([g - uu * m, -p["a3"] * g - uu * s + uu * p["a4"]], axis=1)


@pytest.mark.parametrize("system, steps, vectorized", [
    (BioreactorBullinger(), 2, False),
    (JoSonExample(), 1, False),
    (BatchedBullinger(), 2, True),
])
def test_ode_batch_equals_single_and_the_step_loop(system, steps, vectorized):
    plant = OdePlant(system, dt=0.01, physics_dt=0.005)
    n, m = len(system.state_names), len(system.input_names)
    X0, U = members(n, m, 200, seed=2, scale_x=0.01, scale_u=0.05)
    X0 += np.array(system.default_x0)
    U = np.abs(U) if isinstance(system, BioreactorBullinger) else U
    plant.reset(X0)
    X, Yc = plant.run(U, steps)
    assert hasattr(type(system), "dynamics_batch") == vectorized
    # the reference integrates each member through the 1-D ``dynamics`` (for the vectorized
    # system: its parent, which has no dynamics_batch)
    plain = BioreactorBullinger if vectorized else type(system)
    assert not hasattr(plain, "dynamics_batch")
    ref = OdePlant(plain(), dt=0.01, physics_dt=0.005)
    alone = OdePlant(type(system)(), dt=0.01, physics_dt=0.005)
    for b in range(B):
        Xr, Yr, xe, te = step_loop(ref, X0[b], U[b], steps)
        np.testing.assert_array_equal(X[b], Xr)
        np.testing.assert_array_equal(Yc[b], Yr)
        np.testing.assert_array_equal(plant.state[b], xe)
        assert plant.t == te
        if b < 4:
            alone.reset(X0[b])
            X1, Y1 = alone.run(U[b:b + 1], steps)
            np.testing.assert_array_equal(X1[0], Xr)
            np.testing.assert_array_equal(Y1[0], Yr)


@pytest.mark.parametrize("cuts", [(1,) * 20, (7, 13), (20,)])
def test_ode_blocks_cut_anywhere(cuts):
    plant = OdePlant(JoSonExample(), dt=0.01)
    X0, U = members(3, 1, 20, seed=8)
    plant.reset(X0[:4])
    whole = plant.run(U[:4], 3)
    plant.reset(X0[:4])
    parts, j = [], 0
    for c in cuts:
        parts.append(plant.run(U[:4, j:j + c], 3)[0])
        j += c
    np.testing.assert_array_equal(np.concatenate(parts, axis=1), whole[0])


@pytest.mark.parametrize("system", [BioreactorBullinger(), BatchedBullinger()])
def test_ode_divergence_and_bad_input_name_member_and_time(system):
    plant = OdePlant(system, dt=0.1)
    X0 = np.tile(system.default_x0, (4, 1))
    U = np.full((4, 10, 1), 0.1)
    U[2, 6, 0] = np.nan
    plant.reset(X0)
    with pytest.raises(DivergenceError, match=r"member 2: input u must be finite; found \[nan\] "
                                              r"at t=0.6") as info:
        plant.run(U, 1)
    assert info.value.rows == 7 and info.value.member == 2
    X0[1] = [1e308, 1e308]
    U = np.full((4, 10, 1), 0.1)
    U[1] = 1e308
    plant.reset(X0)
    with np.errstate(over="ignore", invalid="ignore"):
        with pytest.raises(DivergenceError, match=rf"member 1: {type(system).__name__} state left "
                                                  r"the finite numbers at t=0.1"):
            plant.run(U, 1)


def test_ode_unbatched_stays_1d_and_batched_step():
    plant = OdePlant(JoSonExample(), dt=0.01)
    plant.reset()
    assert plant.state.shape == (3,) and plant.outputs().shape == (1,)
    plant.reset(batch=2)
    assert plant.state.shape == (2, 3) and plant.outputs().shape == (2, 1)
    plant.step(np.ones((2, 1)))
    ref = OdePlant(JoSonExample(), dt=0.01)
    ref.step([1.0])
    np.testing.assert_array_equal(plant.state, np.tile(ref.state, (2, 1)))
    assert plant.t == ref.t


def test_mujoco_threads_give_the_same_bits():
    X0, U = members(2, 1, 100, seed=12)
    runs = []
    for nthread in (1, 2, 3):
        plant = make_plant("pendulum", 0.002, nthread=nthread)
        plant.reset(X0)
        runs.append(plant.run(U, 2))
    for X, Yc in runs[1:]:
        np.testing.assert_array_equal(X, runs[0][0])
        np.testing.assert_array_equal(Yc, runs[0][1])


@pytest.mark.parametrize("B_", [1, 6])
def test_mujoco_a_member_the_rollout_stopped_is_stepped_again(B_, monkeypatch):
    """The rollout stops a member at any MuJoCo warning (not only a bad-state reset) and
    repeats its state: seen by its time column, the member is stepped again in the loop, which
    gives what mj_step gives."""
    X0, U = members(2, 1, 120, seed=13)
    plant = make_plant("pendulum", 0.002)
    plant.reset(X0[:B_])
    ref = plant.run(U[:B_], 2), plant.state

    class Freezing:
        """A pool whose rollout freezes the last member after 37 steps."""

        def __init__(self, pool):
            self.pool = pool

        def rollout(self, *args, state, **kw):
            self.pool.rollout(*args, state=state, **kw)
            state[-1, 37:] = state[-1, 36]
            return state, kw.get("sensordata")

    pool, datas = plant._rollout_pool()
    monkeypatch.setattr(plant, "_rollout_pool", lambda: (Freezing(pool), datas))
    plant.reset(X0[:B_])
    got = plant.run(U[:B_], 2), plant.state
    np.testing.assert_array_equal(got[0][0], ref[0][0])
    np.testing.assert_array_equal(got[0][1], ref[0][1])
    np.testing.assert_array_equal(got[1], ref[1])


@pytest.mark.parametrize("name", ["pendulum", "elastic_joint_2link"])
def test_short_blocks_and_member_restart_equal_the_plant_alone(name):
    """Short blocks of a batch (``mujoco.batch``) and ``reset_members``: member 1, restarted
    from a new state, runs as the plant reset alone from it; the others go on."""
    plant, alone = make_plant(name, 0.002), make_plant(name, 0.002)
    assert plant._batch_map is not None  # the short-block path serves these plants
    n, m = len(plant.state_names), len(plant.input_names)
    rng = np.random.default_rng(5)
    X0 = rng.uniform(-0.3, 0.3, (3, n))
    plant.reset(X0, batch=3)
    U = rng.uniform(-0.5, 0.5, (3, 4, m))
    X, Y = plant.run(U, 2)
    alone.reset(X0[2])
    Xa, Ya = alone.run(U[2:3], 2)
    np.testing.assert_array_equal(X[2], Xa[0])
    np.testing.assert_array_equal(Y[2], Ya[0])
    others = plant.state[[0, 2]]
    x_new = rng.uniform(-0.3, 0.3, n)
    plant.reset_members([1], x_new[None])
    np.testing.assert_array_equal(plant.state[[0, 2]], others)
    alone.reset(x_new)
    np.testing.assert_array_equal(plant.outputs()[1], alone.outputs())
    U2 = rng.uniform(-0.5, 0.5, (3, 3, m))
    X, Y = plant.run(U2, 2)
    Xa, Ya = alone.run(U2[1:2], 2)
    np.testing.assert_array_equal(X[1], Xa[0])
    np.testing.assert_array_equal(Y[1], Ya[0])
    np.testing.assert_array_equal(plant.state[1], alone.state)


def test_reset_members_refuses_bad_input():
    plant = make_plant("pendulum", 0.002)
    with pytest.raises(DesignError, match="needs a batch of several members"):
        plant.reset_members([0], np.zeros((1, 2)))
    plant.reset(np.zeros((3, 2)), batch=3)
    with pytest.raises(DimensionError, match=r"X0 must have shape \(1, 2\); found \(1, 3\)"):
        plant.reset_members([0], np.zeros((1, 3)))
    with pytest.raises(DesignError, match=r"x0\[2\]: .* = nan is a state MuJoCo cannot take"):
        plant.reset_members([2], np.array([[np.nan, 0.0]]))
