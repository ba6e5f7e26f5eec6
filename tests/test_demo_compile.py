"""A newcomer's first run compiles each kernel once: no second signature for the same call.

Numba compiles a read-only array argument as a signature of its own.  A test's arrays are
read-only, the calibration's input path is a writable copy, so predicting along a test used to
compile the batched force kernel a second time (about 40 s of the cold `rrfrei demo --quick` for
bouc_wen, measured with Numba's compile events).
"""

from __future__ import annotations

import numpy as np
from numba.core import types

from rrfrei.calibration import setup_problem
from rrfrei.calibration.likelihood import batch_kernels, law_forces
from rrfrei.io import load_test
from rrfrei.laws import get


def _readonly_args(dispatcher) -> list:
    """The dispatcher's signatures with a read-only array argument."""
    return [sig for sig in dispatcher.signatures
            if any(isinstance(a, types.Array) and not a.mutable for a in sig)]


def test_forces_along_a_read_only_test_reuse_the_calibration_signature():
    spec = get("plasticity")
    test = load_test("protocol1")
    assert not test.disp.flags.writeable  # a test's arrays are read-only
    prob = setup_problem(test, spec)
    P = np.atleast_2d(spec.pack({"k_init": 300.0, "qd": 1.5, "alpha1": 0.3, "alpha2": 0.0, "mu": 2.0}))
    F_path, _ = prob.forces(P)
    F_test, status = law_forces(spec, P, test)
    assert status[0] == 0 and np.all(np.isfinite(F_test))
    assert _readonly_args(batch_kernels(spec).forces_batch) == []


_SHARE_ONE_SIGNATURE = """
import numpy as np
from numba.core import types
from rrfrei import simulate_force
from rrfrei.io import load_test
from rrfrei.laws import get
from rrfrei.laws.specialise import history

test = load_test("protocol2")
p = {"k_init": 300.0, "qd": 1.5, "alpha1": 0.3, "alpha2": 0.0, "mu": 2.0}
f_ro = simulate_force("plasticity", p, test.disp, time=test.time)
f_rw = simulate_force("plasticity", p, np.array(test.disp), time=np.array(test.time))
assert np.array_equal(f_ro, f_rw)
sigs = history(get("plasticity"), False).signatures
ro = [s for s in sigs if any(isinstance(a, types.Array) and not a.mutable for a in s)]
print(len(sigs), len(ro))
"""


def test_simulating_a_read_only_test_and_a_writable_history_share_one_signature():
    """The gap step simulates along a test (read-only), the propagation step along a fresh array:
    one compiled history driver serves both.  In a fresh interpreter, so that no other test of
    the same worker has compiled a read-only signature of the driver first."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _SHARE_ONE_SIGNATURE], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    n_sigs, n_readonly = map(int, out.stdout.split())
    assert n_readonly == 0 and n_sigs >= 1


_ONE_LOOP_FOR_EVERY_CALLER = """
import numpy as np
from rrfrei import simulate_force
from rrfrei.calibration import setup_problem
from rrfrei.gap.isolator import simulate_retry
from rrfrei.io import load_test
from rrfrei.laws import _bouc_wen_fast, get
from rrfrei.laws.specialise import history

spec = get("bouc_wen")
test = load_test("protocol1")
p = {"k_init": 1130.0, "qd": 3.1, "alpha1": 0.45, "alpha2": -0.7, "mu": 1.55, "eta": 1.37,
     "beta": 0.5, "gamma": 0.35}
prob = setup_problem(test, spec)                      # the calibration's batched kernel
prob.forces(np.atleast_2d(spec.pack(p)))
simulate_retry(spec, spec.pack(p), test)              # the gap engine, along the read-only test
simulate_force("bouc_wen", p, np.array(test.disp))    # a user's own history
print(len(history(spec).signatures), len(_bouc_wen_fast._fast_run.signatures))
"""


def test_the_calibration_the_gap_engine_and_a_user_compile_one_bouc_wen_loop():
    """bouc_wen's fast loop costs about 15 s of CPU to compile: the calibration's batch (which
    used to pass the literal 1 sub-step, a signature of its own), the gap engine (which passed a
    test's read-only arrays) and ``simulate_force`` share one compiled loop.  Fresh interpreter."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _ONE_LOOP_FOR_EVERY_CALLER], capture_output=True,
                         text=True, timeout=900)
    assert out.returncode == 0, out.stderr
    loop, fast = map(int, out.stdout.split())
    # one signature of the loop (it loads from the kernel cache or compiles, either way one); the
    # fast solver inside it is compiled here only with an empty cache, so at most one
    assert loop == 1 and fast <= 1


def test_a_record_and_a_fresh_ground_array_share_one_newmark_signature():
    """A bundled record's acceleration is read-only, a user's (or an interpolated) one writable:
    the Newmark kernels (unidirectional, its batch, and in plan) are compiled once for both, not
    a second time (about 10 s of CPU per law and kernel) for the read-only record."""
    from dataclasses import replace

    import ground_motions
    import structures
    from rrfrei.laws import plan as plan_laws
    from structures.dynamics import history, plan_history

    rec = ground_motions.load("elcentro")
    assert not rec.accel.flags.writeable  # a record's arrays are read-only
    short = ground_motions.Record(rec.name, rec.dt, rec.accel[:200], rec.meta)
    assert not short.accel.flags.writeable
    b = structures.load_building("three_story")
    bld = replace(b, isolator=structures.Isolator("linear", {"k": 300.0, "c": 0.0}, b.isolator.count,
                                                  b.isolator.length_scale))
    spec = bld.isolator.spec
    ro = structures.time_history(bld, short)
    fresh = ground_motions.Record(rec.name, rec.dt, np.array(short.accel), rec.meta)
    rw = structures.time_history(bld, fresh)
    np.testing.assert_array_equal(ro.isolator_disp, rw.isolator_disp)
    P = np.atleast_2d(bld.isolator.packed())
    structures.time_history_batch(bld, short, P)
    pair = np.column_stack((short.accel, short.accel))
    pair.flags.writeable = False
    structures.plan_time_history(bld, None, None, pair, dt=rec.dt)
    pspec = plan_laws.get("linear")
    # (the batch runs the compiled ``integrate``: tests/test_batch_threads.py)
    assert _readonly_args(history.kernel(spec).integrate) == []
    assert _readonly_args(plan_history.kernel(pspec).integrate) == []
