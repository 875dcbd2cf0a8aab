"""Studies: sweeps over gains, noise, periods, initial states, observers and plants, planned
for the batch (:mod:`hgo_mj.study.engine`), run on local processes or Ray, written to
Parquet; and the older seeds-only Monte Carlo (:mod:`hgo_mj.study.montecarlo`)."""

from .montecarlo import (
    MonteCarloResult,
    aggregate,
    check_seeds,
    format_mc_table,
    monte_carlo,
    run_seed,
    run_seeds,
)
from .spec import StudySpec, parse_study
from .study import Study, StudyResult, load_toml

__all__ = ["MonteCarloResult", "Study", "StudyResult", "StudySpec", "aggregate", "check_seeds",
           "format_mc_table", "load_toml", "monte_carlo", "parse_study", "run_seed", "run_seeds"]
