"""The Ray backend on a real local Ray instance (127.0.0.1, 2 CPUs, no dashboard): the same
rows as the local backend."""

from __future__ import annotations

import pandas as pd
import pytest
import ray

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError
from hgo_mj.study import Study
from hgo_mj.study.backends import backend_for

BASE = {
    "name": "ray",
    "plant": {"name": "pendulum", "dt": 0.001, "x0": [0.5, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    "run": {"duration": 0.5, "seed": 0},
}
AXES = {"observers.hgo.k": [10.0, 40.0], "plant.x0": [[0.5, 0.0], [1.0, 0.0]]}


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, _node_ip_address="127.0.0.1",
             log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


def test_ray_gives_the_rows_of_the_local_backend(local_ray, tmp_path):
    local = Study(BASE, AXES, seeds=3).run(tmp_path / "local", quiet=True).table
    on_ray = Study(BASE, AXES, seeds=3).run(tmp_path / "ray", jobs=2, backend="ray",
                                            quiet=True).table
    cols = [c for c in local.columns if c != "update_time"]
    assert len(local) == 2 * 2 * 3 * 2
    pd.testing.assert_frame_equal(on_ray[cols], local[cols])


def test_an_unknown_backend_and_an_address_without_ray_are_refused():
    with pytest.raises(DesignError, match=r"backend must be one of \['local', 'ray'\]"):
        backend_for("dask")
    with pytest.raises(DesignError, match="--address is for --backend ray"):
        backend_for("local", address="127.0.0.1:6379")


def test_an_unreachable_ray_address_is_one_line(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text('[plant]\nname = "pendulum"\n[[observers]]\ntype = "high_gain"\nk = 20.0\n'
                 '[run]\nduration = 0.1\n[sweep]\nseeds = 1\n')
    ray.shutdown()  # the command line's process has no Ray instance of its own
    code = main(["sweep", str(f), "--out", str(tmp_path / "o"), "--backend", "ray",
                 "--address", "127.0.0.1:1", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "cannot start or reach Ray at '127.0.0.1:1'" in err
