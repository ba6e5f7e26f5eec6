"""A law's OpenSees element and argument list live in its spec (issue 28.3): the exported
command, the differential-test harnesses and the plan tests read ``LawSpec.opensees`` and
nobody else spells an argument list.  The peer checks (the element built from these lists
reproduces the law) are in test_calibration_export.py, test_laws_opensees.py and
test_plan_laws_opensees.py."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rrfrei.calibration.results import opensees_command
from rrfrei.laws import OpenSeesElement, get, opensees_laws, plan

ROOT = Path(__file__).resolve().parents[1]
PARAMS = {
    "plasticity": dict(k_init=260.0, qd=1.4, alpha1=0.33, alpha2=0.05, mu=2.5),
    "bouc_wen": dict(k_init=260.0, qd=1.4, alpha1=0.33, alpha2=0.05, mu=2.5, eta=1.37, beta=0.6,
                     gamma=0.4),
    "elastomeric_x": dict(fy=1.4, alpha=0.33, gr=513.0, d2=0.08, tr=0.002, n=15.0),
    "hdr": dict(a1=150.0, a2=1.6e4, a3=2.3e6, b1=1.2, b2=550.0, b3=200.0, c1=30.0, c2=30.0, c3=0.8,
                c4=0.5),
}
ORIENT3 = (0.0, 0.0, 1.0, 1.0, 0.0, 0.0)


def test_every_opensees_law_declares_its_element_and_a_parameter_case_here():
    assert set(opensees_laws()) == set(PARAMS)
    for law in opensees_laws():
        assert isinstance(get(law).opensees, OpenSeesElement)
    assert get("linear").opensees is None and get("linear").opensees_element == ""


@pytest.mark.parametrize("law,count,at", [("elastomeric_x", 29, 9), ("hdr", 32, 17)])
def test_the_3d_only_elements_receive_every_positional_argument(law, count, at):
    """ElastomericX reads 29 positional values after ``element``, HDR 32 (tag and nodes
    included), as ``OPS_ElastomericX`` / ``OPS_HDR`` read them, the orientation vectors after
    the shear law's (x1 x2 x3 y1 y2 y3 at argument ``at``)."""
    orient = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    args = get(law).opensees_args(PARAMS[law], ndm=3, orient=orient)
    assert 3 + len(args) == count
    assert tuple(args[at:at + 6]) == orient


@pytest.mark.parametrize("law", ["plasticity", "bouc_wen"])
def test_a_bearing_element_takes_the_parameters_in_order_then_materials_and_orientation(law):
    spec = get(law)
    p = PARAMS[law]
    two = spec.opensees_args(p, ndm=2, orient=(0, 1, 0, -1, 0, 0))
    assert two == [*(p[n] for n in spec.param_names), "-P", 1, "-Mz", 2, "-orient", 0, 1, 0, -1, 0, 0]
    three = spec.opensees_args(p, ndm=3, orient=ORIENT3, materials=(5, 6, 7, 8))
    assert three[len(p):] == ["-P", 5, "-T", 6, "-My", 7, "-Mz", 8, "-orient", *ORIENT3]


def test_optional_parameters_take_their_defaults_in_the_argument_list():
    args = get("elastomeric_x").opensees_args(PARAMS["elastomeric_x"], ndm=3, orient=ORIENT3)
    full = get("elastomeric_x").opensees_args(
        {**PARAMS["elastomeric_x"], "d1": 0.0, "tc": 0.0, "cd": 0.0}, ndm=3, orient=ORIENT3)
    assert args == full


def test_bad_requests_name_what_is_wrong():
    with pytest.raises(ValueError, match=r"ElastomericX exists only in 3-D models, got ndm = 2"):
        get("elastomeric_x").opensees_args(PARAMS["elastomeric_x"], ndm=2, orient=ORIENT3)
    with pytest.raises(ValueError, match=r"parameter qd = -1 .* outside"):
        get("plasticity").opensees_args({**PARAMS["plasticity"], "qd": -1.0}, ndm=2, orient=ORIENT3)
    with pytest.raises(ValueError, match=r"orient needs 6 numbers"):
        get("plasticity").opensees_args(PARAMS["plasticity"], ndm=2, orient=(0, 1, 0))
    with pytest.raises(ValueError, match=r"takes 2 material tags"):
        get("plasticity").opensees_args(PARAMS["plasticity"], ndm=2, orient=ORIENT3, materials=(1,))
    with pytest.raises(ValueError, match=r"'linear' has no OpenSees element"):
        get("linear").opensees_args({"k": 1.0}, ndm=2, orient=ORIENT3)
    with pytest.raises(ValueError, match=r"'linear' has no OpenSees element"):
        opensees_command(get("linear"), {"k": 1.0})


def test_the_exported_command_is_built_from_the_spec_not_from_the_law_name():
    """A spec with another argument list exports that list: no switch on law names."""
    spec = get("plasticity")
    other = dataclasses.replace(spec, name="plasticity_variant", opensees=OpenSeesElement(
        "myBearing", lambda p, ndm, orient, materials=None: [p["qd"], "-orient", *orient]))
    cmd = opensees_command(other, PARAMS["plasticity"])
    assert cmd == "ops.element('myBearing', 1, 1, 2, 1.4, '-orient', 0.0, 1.0, 0.0, 1.0, 0.0, 0.0)"


def test_a_plan_law_builds_its_laws_element_in_3d():
    for name in plan.names():
        spec = plan.get(name)
        assert spec.opensees_element == spec.law.opensees_element
        if spec.opensees_element:
            assert spec.opensees_args(PARAMS[name], orient=ORIENT3) == \
                spec.law.opensees_args(PARAMS[name], ndm=3, orient=ORIENT3)


def test_the_harnesses_build_the_elements_the_specs_declare():
    from tests import opensees_harness, opensees_plan

    for law in opensees_laws():
        spec = get(law)
        ndm = 2 if 2 in spec.opensees.dims else 3
        orient = opensees_harness.ORIENT[ndm]
        assert opensees_harness.opensees_ndm(law) == ndm
        assert opensees_harness._element_args(law, PARAMS[law]) == [
            spec.opensees_element, 1, 1, 2, *spec.opensees_args(PARAMS[law], ndm=ndm, orient=orient)]
        assert opensees_plan._plan_element_args(law, PARAMS[law]) == [
            spec.opensees_element, 1, 1, 2, *plan.get(law).opensees_args(PARAMS[law],
                                                                         orient=opensees_plan.ORIENT)]


@pytest.mark.parametrize("path", ["rrfrei/calibration/results.py", "tests/opensees_harness.py",
                                  "tests/opensees_plan.py", "tests/opensees_dynamic.py",
                                  "tests/opensees_plan_building.py"])
def test_no_reader_of_the_spec_spells_an_element_name(path):
    """The element names are string constants in the law modules only (one place per law)."""
    names = {get(law).opensees_element for law in opensees_laws()}
    tree = ast.parse((ROOT / path).read_text())
    spelled = {node.value for node in ast.walk(tree)
               if isinstance(node, ast.Constant) and node.value in names}
    assert not spelled, f"{path} spells {sorted(spelled)}"


def test_the_argument_values_are_the_parameters_not_copies_of_them():
    """A parameter change moves exactly its argument (the vertical constants stay)."""
    spec = get("hdr")
    a = spec.opensees_args(PARAMS["hdr"], ndm=3, orient=ORIENT3)
    b = spec.opensees_args({**PARAMS["hdr"], "b3": 321.0}, ndm=3, orient=ORIENT3)
    diff = [i for i, (x, y) in enumerate(zip(a, b)) if x != y]
    assert len(diff) == 1 and b[diff[0]] == 321.0 and np.isfinite(a[diff[0]])
