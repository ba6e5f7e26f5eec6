"""The calibration's arviz statistics (summary ESS and R-hat, PSIS-LOO) run on arviz' NumPy
paths: its Numba helpers are compiled afresh, uncached, in every process (about 2 s of the
2,401-point ``rrfrei calibrate``, issue 28.7), and the NumPy paths give the same numbers."""

from __future__ import annotations

import json
import subprocess
import sys

PROBE = """
import json, warnings
import numpy as np
from rrfrei.calibration.results import arviz_numpy, load_arviz, summary_table
from rrfrei.laws import get

az = load_arviz()
rng = np.random.default_rng(0)
post = {"k": 100 + rng.standard_normal((8, 50)).cumsum(axis=1), "sigma": 1 + 0.1 * rng.random((8, 50))}
ll = rng.standard_normal((8, 50, 40)) - 1.0
idata = az.from_dict(posterior=post, log_likelihood={"force": ll})
flag = az.Numba.numba_flag
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    table = summary_table(idata, get("linear"), {"k": 100.0, "sigma": 1.0}, ("k",), "iid")
    with arviz_numpy() as a:
        loo = float(a.loo(idata, var_name="force").elpd_loo)
    from arviz.stats.stats_utils import stats_variance_1d
    compiled = list(getattr(stats_variance_1d.__dict__.get("numba_fn"), "signatures", []))
    restored = az.Numba.numba_flag == flag
    az.Numba.numba_flag = True  # arviz' own Numba path, for the reference numbers
    ess = az.ess(idata, var_names=["k", "sigma"], method="bulk")
    rhat = az.rhat(idata, var_names=["k", "sigma"])
    loo_numba = float(az.loo(idata, var_name="force").elpd_loo)
print(json.dumps({"compiled": [str(s) for s in compiled], "restored": restored,
                  "ess": [table.loc[n, "ESS"] - float(ess[n]) for n in ("k", "sigma")],
                  "rhat": [table.loc[n, "R-hat"] - float(rhat[n]) for n in ("k", "sigma")],
                  "loo": loo - loo_numba}))
"""


def test_summary_and_loo_compile_no_arviz_numba_helper_and_match_its_numbers():
    run = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, check=True)
    r = json.loads(run.stdout.strip().splitlines()[-1])
    assert r["compiled"] == []  # nothing jitted by the summary or the LOO
    assert r["restored"]  # the flag is arviz' own again after the block
    assert max(abs(x) for x in r["ess"]) < 1e-6
    assert max(abs(x) for x in r["rhat"]) < 1e-10
    assert abs(r["loo"]) < 1e-9
