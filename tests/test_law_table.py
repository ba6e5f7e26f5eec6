"""The law table is the single source (issue 13.1): specifications of the registry, the effect
table and the template mechanism (:mod:`rrfrei.laws.specialise`)."""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rrfrei
from rrfrei.laws import LawSpec, ParamSpec, get, names, specialise
from rrfrei.laws.effects import EFFECTS, EffectSpec

ROOT = Path(__file__).resolve().parents[1]
BUILTIN = ("plasticity", "bouc_wen", "elastomeric_x", "hdr", "linear")


def test_names_lists_the_builtin_laws_in_a_fixed_order_whatever_was_imported_first():
    assert tuple(n for n in names() if n in BUILTIN) == BUILTIN
    # a fresh interpreter that imports the laws in reverse order registers them in that order
    code = ("import rrfrei.laws.linear, rrfrei.laws.hdr, rrfrei.laws.elastomeric_x, "
            "rrfrei.laws.bouc_wen; from rrfrei import laws; print(','.join(laws.names()), "
            "','.join(laws.OPENSEES_LAWS))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == [",".join(BUILTIN), ",".join(BUILTIN[:4])]


def test_every_module_of_the_laws_package_is_found_without_an_import_list():
    source = (ROOT / "rrfrei" / "laws" / "__init__.py").read_text()
    for name in BUILTIN:
        assert f"import {name}" not in source and f" {name}," not in source
    code = "from rrfrei.laws import get; print(get('hdr').name)"  # the first lookup discovers
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "hdr", out.stderr[-2000:]


def test_every_module_of_the_effects_package_is_one_effect_of_the_table():
    modules = sorted(p.stem for p in (ROOT / "rrfrei" / "laws" / "effects").glob("*.py")
                     if not p.stem.startswith("_"))
    assert sorted(EFFECTS) == modules
    for name, eff in EFFECTS.items():
        assert isinstance(eff, EffectSpec) and eff.name == name
        assert (eff.apply is None) != (eff.capacity is None)


def test_the_bindings_of_a_law_are_its_registry_kernels():
    bw = get("bouc_wen")
    assert specialise.bindings(bw) == {"law_step": bw.step, "law_step_robust": bw.step_robust}
    pl = get("plasticity")
    assert specialise.bindings(pl) == {"law_step": pl.step, "law_step_robust": pl.step}
    fast = specialise.history_bindings(bw)  # the one history loop, bw's fast solver in its slot
    assert fast["law_step"] is bw.step and fast["law_run"] is bw.fast_run
    assert specialise.history_bindings(bw, robust=True)["law_step"] is bw.step_robust
    assert specialise.history_bindings(pl)["law_run"] is specialise.history_bindings(pl, True)["law_run"]
    for law in (bw, pl):  # every law's driver is an instance of the one loop
        for robust in (False, True):
            file = Path(specialise.history(law, robust).py_func.__code__.co_filename).name
            assert file.startswith(f"rrfrei_laws__history__{law.name}_")
    aug = get("plasticity+rate")
    assert specialise.bindings(aug)["law_step"] is aug.step  # an instance, like any other step
    assert specialise.history(aug) is specialise.history(aug)  # one instance per law


def test_every_history_driver_is_an_instance_of_the_one_loop_of_its_dimension():
    """One whole-history loop per dimension: a law brings its local solver (and a fast solver, a
    scalar carrier) as slots, never a loop of its own."""
    from rrfrei.laws import plan

    for name in names():
        for robust in (False, True):
            file = Path(specialise.history(get(name), robust).py_func.__code__.co_filename).name
            assert file.startswith(f"rrfrei_laws__history__{name}_"), (name, robust, file)
    for name in plan.names():
        for drive in (plan.registry.driver(plan.get(name)), plan.registry.generic_driver(plan.get(name))):
            file = Path(drive.py_func.__code__.co_filename).name
            assert file.startswith(f"rrfrei_laws_plan__history__plan_{name}_"), (name, file)


def test_a_law_entry_without_a_kernel_is_refused_naming_the_field():
    with pytest.raises(ValueError, match=r"law 'nokernel': step = None is not a kernel"):
        LawSpec(name="nokernel", params=(ParamSpec("k", "kN/m", 0.0, 1.0, "k"),), state_size=0,
                description="-")
    with pytest.raises(ValueError, match=r"initial_state has shape \(2,\), expected \(1,\)"):
        LawSpec(name="badstate", params=(), state_size=1, description="-", step=get("linear").step,
                initial_state=np.zeros(2))


def test_instantiate_binds_constants_and_refuses_missing_unknown_or_non_finite_bindings():
    tmpl = "rrfrei.laws.effects._augment"
    good = {s: 0 for s in __import__(tmpl, fromlist=["SLOTS"]).SLOTS}
    with pytest.raises(ValueError, match=r"missing bindings \['NB'\]"):
        specialise.instantiate(tmpl, {k: v for k, v in good.items() if k != "NB"}, "x")
    with pytest.raises(ValueError, match=r"unknown \['nope'\]"):
        specialise.instantiate(tmpl, {**good, "nope": 1}, "x")
    with pytest.raises(ValueError, match="slot 'NB': constant nan must be"):
        specialise.instantiate(tmpl, {**good, "NB": float("nan")}, "x")


def test_a_registered_law_pickles_by_name():
    for name in ("plasticity", "bouc_wen+rate+slip"):
        spec = get(name)
        assert pickle.loads(pickle.dumps(spec)) is spec


def test_augmented_laws_compose_effects_in_the_order_named_with_offsets_into_p_and_state():
    spec = get("plasticity+degradation+slip+rate")
    assert spec.param_names[-12:] == ("deg_rate", "deg_travel", "deg_exp", "slip_force", "slip_stick",
                                      "slip_static", "slip_dc", "rate_c", "rate_exp", "rate_sat", "rate_rise",
                                      "rate_vsat")
    assert spec.state_size == 1 + 5 + 2
    with pytest.raises(ValueError, match="at most 4 effects"):
        get("plasticity+degradation+slip+rate+mullins+asymmetry")
    u = np.linspace(0.0, 0.03, 50)
    p = dict(k_init=100.0, qd=1.0, alpha1=0.1, alpha2=0.0, mu=2.0)
    f = rrfrei.simulate_force("plasticity+slip", {**p, "slip_force": 1.1}, u)
    assert np.abs(f).max() == pytest.approx(1.1, rel=1e-9)  # the slider caps the force (1.3 kN without)
