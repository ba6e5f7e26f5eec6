"""Smaller traps a user hit: each gets the behaviour a user expects (issue 16.6)."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import pytest

import structures
from rrfrei.app import cli


@pytest.mark.parametrize("option", ["--steps", "--walkers"])
def test_zero_steps_or_walkers_is_an_error_naming_the_option_not_a_silent_default(option, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["calibrate", "protocol1", "--law", "linear", "--out", "unused", option, "0"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert option in err and "expected an integer >= 2" in err and len(err.strip().splitlines()) == 1


def test_a_command_module_that_fails_to_import_is_not_silently_dropped(monkeypatch):
    import rrfrei.app.commands

    # a command's module is imported when the command runs (or when every parser is built):
    # one that cannot be imported stops it with an error naming it (never a CLI without it)
    monkeypatch.setitem(sys.modules, "rrfrei.app.commands.gap_validate", None)  # not importable
    monkeypatch.delattr(rrfrei.app.commands, "gap_validate", raising=False)
    with pytest.raises(ImportError, match="gap_validate"):
        cli.build_parser()
    with pytest.raises(ImportError, match="gap_validate"):
        cli.main(["gap-validate", "--help"])
    broken = types.ModuleType("rrfrei.app.commands.broken")  # no register(): a bug
    monkeypatch.setitem(sys.modules, "rrfrei.app.commands.broken", broken)
    monkeypatch.setitem(rrfrei.app.commands.HELPS, "broken", "a command without register()")
    monkeypatch.setattr(cli, "COMMANDS", (*cli.COMMANDS, "broken"))
    with pytest.raises(AttributeError, match="register"):
        cli.build_parser(["broken"])


def test_load_building_reads_a_toml_path_and_lists_bundled_names_for_an_unknown_one(tmp_path):
    bundled = Path(structures.__file__).parent / "building" / "buildings" / "three_story.toml"
    mine = tmp_path / "my.toml"
    mine.write_text(bundled.read_text())
    by_path = structures.load_building(str(mine))
    named = structures.load_building("three_story")
    assert by_path.name == "my"
    assert by_path.story_masses == named.story_masses and by_path.isolator == named.isolator
    assert structures.load_building(mine) == by_path
    with pytest.raises(FileNotFoundError):
        structures.load_building(str(tmp_path / "missing.toml"))
    with pytest.raises(ValueError, match="five_story.*three_story|three_story.*five_story"):
        structures.load_building("ten_story")


def test_the_cli_names_columns_of_a_raw_lab_file_without_renaming_them():
    """SPC1.csv (real timber test): force first, 'Lead Actuator Displacment' (sic), a units row."""
    from _shared import shared

    from rrfrei.app.commands.calibrate import load
    from rrfrei.io import read_test

    path = shared("data", "hysteresis", "clt_connection_tannert_spc1", "SPC1.csv")
    args = cli.build_parser().parse_args(
        ["calibrate", str(path), "--law", "bouc_wen", "--out", "unused",
         "--disp-col", "Lead Actuator Displacment:mm", "--force-col", "Lead Actuator Force :kN"])
    got = load(str(path), args)
    ref = read_test(path, disp_col="Lead Actuator Displacment", force_col="Lead Actuator Force ")
    assert len(got) == 33028
    assert (got.disp == ref.disp).all() and (got.force == ref.force).all()
    args.disp_col = "Lead Actuator Displacment:furlong"
    with pytest.raises(ValueError, match="furlong"):
        load(str(path), args)


def test_missing_geometry_error_says_where_the_sidecar_is_looked_for():
    import rrfrei

    spec = rrfrei.laws.get("elastomeric_x")
    with pytest.raises(ValueError, match=r"<file>\.toml, <stem>\.toml or geometry\.toml"):
        spec.resolve_fixed()


def test_a_demo_step_writes_an_expected_failure_into_the_page_but_a_bug_propagates():
    from rrfrei.app.demo import DemoContext, DemoSettings, Step, run_step

    def numerical(ctx, sec):
        raise ValueError("law 'bouc_wen' failed at sample 12")

    def bug(ctx, sec):
        raise TypeError("unsupported operand type(s)")

    ctx = DemoContext(DemoSettings(), progress=False)
    sec = run_step(Step("x", "X", numerical), ctx)
    assert "failed at sample 12" in sec.error
    with pytest.raises(TypeError):
        run_step(Step("y", "Y", bug), ctx)


def test_a_checkpoint_without_chain_reads_as_zero_steps_and_other_errors_show(tmp_path):
    import emcee
    import h5py

    from rrfrei.calibration.store import _stored_iterations

    path = tmp_path / "opt.h5"
    with h5py.File(path, "w") as f:
        f.require_group("rrfrei")
    assert _stored_iterations(emcee.backends.HDFBackend(str(path))) == 0

    class Broken:
        @property
        def iteration(self):
            raise TypeError("a bug")

    with pytest.raises(TypeError):
        _stored_iterations(Broken())


@pytest.mark.parametrize("reader", ["rrfrei", "rubber"])
def test_a_binary_file_renamed_csv_gives_an_error_naming_the_file(tmp_path, reader):
    import rrfrei
    import rubber

    path = tmp_path / "test.csv"
    path.write_bytes(b"time_s,disp_mm\n" + bytes(range(128, 256)) * 4)
    read = rrfrei.read_test if reader == "rrfrei" else rubber.read_test
    with pytest.raises(ValueError, match=r"test\.csv.*not a text CSV"):
        read(path)
