"""Compiled code is never stale: an edit to any kernel source reaches every compiled caller.

Numba keys a cached function on its own source file only, so a cached caller in another file
(then ``dispatch.base_step``/``base_drive`` calling ``plasticity.step``; now the per-law instances
of the history driver and of the batched likelihood, generated files that inline the law) used to
keep the old machine code after ``plasticity.py`` changed.  Reproduced as it broke: a copy of the
package, a warm cache, an edit of the elastic branch of one law, then the public functions must
change; and reverting the edit must bring the original numbers back.  The same for a law defined
outside the packages (``tests/_toy_law.py``), which the package-wide source hash does not see.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("rrfrei", "structures", "rubber", "ground_motions")

PROBE = r"""
import json, sys, numpy as np
import rrfrei
from rrfrei.calibration import setup_problem
from rrfrei.io import ShearTest
law = sys.argv[1] if len(sys.argv) > 1 else "plasticity"
if law != "plasticity":
    import _toy_law  # registers the law (defined outside the packages)
u = np.linspace(0.0, 1e-4, 5)              # elastic branch only (u < u_y = 2e-3 m, d_b = 5e-3 m)
p = (dict(k_init=1000.0, qd=2.0, alpha1=0.1, alpha2=0.0, mu=2.0) if law == "plasticity"
     else dict(k=1000.0))
f = rrfrei.simulate_force(law, p, u)
spec = rrfrei.laws.get(law)
fs, kt, status = spec.step(spec.pack(p), np.zeros(spec.state_size), 1e-4, 0.0, 1.0,
                           np.zeros(spec.state_size))
ul = np.linspace(0.0, 1e-4, 12)
prob = setup_problem(ShearTest("probe", np.arange(12.0), ul, 1000.0 * ul), spec)
F, _ = prob.forces(spec.pack(p)[None, :])  # the batched likelihood kernels (per-law instance)
theta = np.array([[p[n] for n in prob.free] + [0.01]])
from rrfrei import _jit_cache
print(json.dumps({"simulate": float(f[-1]), "base_step": float(fs), "batch": float(F[0, -1]),
                  "loglik": float(prob.log_likelihood(theta)[0]), "cache": _jit_cache.CACHE_DIR}))
"""

EDIT_FROM = "        f = q_tr + k2 * u + nl_f\n"
EDIT_TO = "        f = 2.0 * (q_tr + k2 * u + nl_f)\n"


def _run(tree: Path, law: str = "plasticity") -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "_RRFREI_NUMBA_CACHE")}
    env["PYTHONPATH"] = os.pathsep.join([str(tree), str(tree / "tests")])
    env["XDG_CACHE_HOME"] = str(tree / "xdg")
    out = subprocess.run(
        [sys.executable, "-c", PROBE, law], cwd=tree, env=env, capture_output=True, text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.fixture
def tree(tmp_path):
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    (tmp_path / "tests").mkdir()
    shutil.copy(ROOT / "tests" / "_toy_law.py", tmp_path / "tests" / "_toy_law.py")
    return tmp_path


def test_editing_a_law_reaches_callers_in_other_files_and_reverting_restores_it(tree):
    law = tree / "rrfrei" / "laws" / "plasticity.py"
    source = law.read_text()
    assert EDIT_FROM in source, "the probe's edit no longer matches plasticity.py"

    before = _run(tree)
    warm = _run(tree)  # from the cache this time
    assert warm["simulate"] == before["simulate"] == pytest.approx(1000.0 * 1e-4)
    assert warm["cache"] == before["cache"]
    assert Path(before["cache"]).is_relative_to(tree / "xdg"), "the cache lives in the user's cache"

    law.write_text(source.replace(EDIT_FROM, EDIT_TO))
    edited = _run(tree)
    assert edited["cache"] != before["cache"], "an edited kernel source must select a new cache"
    assert edited["simulate"] == pytest.approx(2.0 * before["simulate"], rel=1e-12)
    assert edited["base_step"] == pytest.approx(2.0 * before["base_step"], rel=1e-12)
    assert edited["batch"] == pytest.approx(2.0 * before["batch"], rel=1e-12)
    assert edited["loglik"] != before["loglik"]

    law.write_text(source)
    reverted = _run(tree)
    assert reverted["simulate"] == before["simulate"]
    assert reverted["base_step"] == before["base_step"]
    assert reverted["batch"] == before["batch"]
    assert reverted["loglik"] == before["loglik"]
    assert Path(edited["cache"]).exists(), "a recent cache of other sources stays (a process may use it)"
    old = Path(edited["cache"]).stat().st_mtime - 3 * 3600
    os.utime(edited["cache"], (old, old))
    _run(tree)
    assert not Path(edited["cache"]).exists(), "caches of other source versions are pruned once old"


TOY_FROM = "        return k * u, k, 0\n"
TOY_TO = "        return 2.0 * k * u, k, 0\n"


def test_editing_a_law_outside_the_packages_reaches_its_instances_and_reverting_restores_it(tree):
    """The package-wide cache key cannot see ``tests/_toy_law.py``; the instances' file names hash
    the bound law's source (rrfrei.laws.specialise), so the edit still reaches simulate_force and
    the likelihood, with the same cache folder."""
    law = tree / "tests" / "_toy_law.py"
    source = law.read_text()
    assert TOY_FROM in source, "the probe's edit no longer matches tests/_toy_law.py"

    before = _run(tree, "toy_bilinear")
    warm = _run(tree, "toy_bilinear")
    assert warm == before
    assert before["simulate"] == pytest.approx(1000.0 * 1e-4)

    law.write_text(source.replace(TOY_FROM, TOY_TO))
    edited = _run(tree, "toy_bilinear")
    assert edited["cache"] == before["cache"], "the package sources did not change"
    for key in ("simulate", "base_step", "batch"):
        assert edited[key] == pytest.approx(2.0 * before[key], rel=1e-12), key
    assert edited["loglik"] != before["loglik"]

    law.write_text(source)
    assert _run(tree, "toy_bilinear") == before


def test_a_user_set_numba_cache_dir_holds_the_kernel_cache_still_keyed_on_the_sources(tmp_path):
    """``NUMBA_CACHE_DIR`` chooses where the cache lives (``<it>/rrfrei/numba/k-<hash>``); the
    folder is still named after the kernel sources, so it never goes stale, and neither Numba's
    setting nor the environment is changed."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "mine"))
    env.pop("_RRFREI_NUMBA_CACHE", None)
    out = subprocess.run(
        [sys.executable, "-c", "import rrfrei, os; from numba.core import config; "
         "print(rrfrei._jit_cache.CACHE_DIR, config.CACHE_DIR, os.environ['NUMBA_CACHE_DIR'])"],
        env=env, capture_output=True, text=True, timeout=120, cwd=ROOT,
    )
    assert out.returncode == 0, out.stderr
    ours, numba_dir, env_dir = out.stdout.split()
    from rrfrei import _jit_cache

    assert Path(ours) == tmp_path / "mine" / "rrfrei" / "numba" / f"k-{_jit_cache.source_hash(ROOT)}"
    assert numba_dir == env_dir == str(tmp_path / "mine")


def test_old_cache_folders_go_but_a_running_process_keeps_its_own(tmp_path):
    """A folder of other sources is removed once unchanged for two hours; a recent one (another
    process, started before an edit, may still compile into it) stays, and so does the current."""
    from rrfrei import _jit_cache

    for name in ("k-current", "k-old", "k-recent", "unrelated"):
        (tmp_path / name).mkdir()
    old = (tmp_path / "k-old").stat().st_mtime - 3 * 3600
    os.utime(tmp_path / "k-old", (old, old))
    os.utime(tmp_path / "unrelated", (old, old))
    _jit_cache._prune(tmp_path, "k-current")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k-current", "k-recent", "unrelated"]
