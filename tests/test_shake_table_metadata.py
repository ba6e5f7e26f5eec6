"""Shake-table run metadata (issue 29, item 3): the sampling rate, the level masses and their order
given on the command line or in the sidecar, and the reader's physical checks of them.

Every case is a bundled BNCS run (ICA50, 50 Hz) written back as a raw folder (files a1..a6 with
a1 the roof, d1..d6, u, du, no time, no masses) or as a CSV, with its metadata missing or wrong.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rrfrei.app import cli
from rrfrei.app.commands import shake_table as st_cmd
from structures.shake_table import (
    BNCS_WEIGHTS_KN,
    ConsistencyWarning,
    LevelOrderWarning,
    MetadataError,
    available_runs,
    check_level_order,
    load_run,
    read_run,
    write_run,
)

WEIGHTS = ",".join(f"{w:g}" for w in BNCS_WEIGHTS_KN)  # base slab first
WEIGHTS_ROOF_FIRST = ",".join(f"{w:g}" for w in BNCS_WEIGHTS_KN[::-1])  # the data's own order (a1..a6)


@pytest.fixture(scope="module")
def ica50():
    return load_run("ICA50")


def _write_folder(run, folder: Path, *, a1: str = "roof") -> Path:
    """``run`` in the raw folder layout: a1..aN (a1 the roof unless ``a1="base"``), d1..dN, u, du."""
    folder.mkdir(parents=True, exist_ok=True)
    L = run.n_levels
    for i in range(1, L + 1):
        col = L - i if a1 == "roof" else i - 1
        np.savetxt(folder / f"a{i}.txt", run.accel[:, col], fmt="%.7g")
        np.savetxt(folder / f"d{i}.txt", run.disp[:, col], fmt="%.7g")
    np.savetxt(folder / "u.txt", run.table_accel, fmt="%.7g")
    np.savetxt(folder / "du.txt", run.table_disp, fmt="%.7g")
    return folder


@pytest.fixture(scope="module")
def raw(ica50, tmp_path_factory):
    """ICA50 as a raw folder without any metadata (as the shared BNCS folders come)."""
    return _write_folder(ica50, tmp_path_factory.mktemp("raw") / "ICA50")


def _cli(capsys, *argv) -> tuple[int, str]:
    """Run ``rrfrei shake-table``; ``--calibrate NOPE`` stops it right after reading the runs."""
    try:
        code = cli.main(["shake-table", *argv, "--no-progress"])
    except SystemExit as exc:  # argparse's own errors (a bad choice)
        code = exc.code
    return code, capsys.readouterr().err


def _read(*argv):
    """The runs and notes ``rrfrei shake-table RUN ... OPTIONS`` reads (no pipeline)."""
    import argparse

    from rrfrei.app.commands import shake_table_meta

    p = argparse.ArgumentParser()
    p.add_argument("runs", nargs="*")
    shake_table_meta.add_arguments(p)
    args = p.parse_args([str(a) for a in argv])
    return shake_table_meta.read_runs(args.runs, args)


# ------------------------------------------------------------------- missing metadata, for the CLI
def test_a_raw_folder_without_a_rate_names_the_option_and_the_sidecar_key(raw, capsys):
    code, err = _cli(capsys, str(raw))
    assert code == 2
    assert "sampling rate is not stated" in err and "--rate-hz" in err and "rate_hz" in err
    assert str(raw / "run.toml") in err and "docs/shake_table_data.md" in err
    assert "rate_hz=" not in err  # not the Python argument


def test_a_raw_folder_without_masses_names_the_options_and_the_sidecar_keys(raw, capsys):
    code, err = _cli(capsys, str(raw), "--rate-hz", "50")
    assert code == 2
    assert "no level masses" in err and "--weights" in err and "--masses" in err
    assert "[levels] weights" in err and "--level-order" in err
    assert "weights=" not in err and "masses=" not in err


def test_metadata_from_the_command_line_reads_a_raw_folder_like_its_bundled_copy(raw, ica50):
    """Weights in kN (by --weight-unit or a suffix) are masses W / 9.81 [t]; roof-first lists
    stated as such come out bottom-up; the channels are the bundled run's."""
    for argv in (["--weights", WEIGHTS, "--weight-unit", "kN"],
                 ["--weights", WEIGHTS.replace(",", "kN,") + "kN"],
                 ["--weights", WEIGHTS_ROOF_FIRST, "--weight-unit", "kN", "--level-order", "roof-first"],
                 ["--masses", ",".join(f"{m:.10g}" for m in ica50.masses)]):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no warning on correct metadata
            (run,), notes = _read(raw, "--rate-hz", "50", *argv)
        assert notes == []
        np.testing.assert_allclose(run.masses, ica50.masses, rtol=1e-9)
        np.testing.assert_allclose(run.accel, ica50.accel, rtol=1e-6, atol=1e-9)
        assert run.rate_hz == pytest.approx(50.0)


@pytest.mark.parametrize("argv, words", [
    (["--weights", WEIGHTS], "has no unit"),
    (["--weights", "2275.1kN,674t"], "unit 't'"),
    (["--weights", "2275.1kN,674N"], "mixed units"),
    (["--weights", WEIGHTS, "--weight-unit", "kN", "--masses", "1,2"], "not both"),
    (["--masses", "1,2,x"], "item 3 'x'"),
    (["--weights", "1,2,3", "--weight-unit", "kN"], "3 level masses for 6 levels"),
    (["--weights", WEIGHTS, "--weight-unit", "kN", "--level-order", "top-down"], "--level-order"),
])
def test_bad_metadata_options_exit_2_with_one_line(raw, capsys, argv, words):
    code, err = _cli(capsys, str(raw), "--rate-hz", "50", *argv)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1


# ------------------------------------------------------------------------------ a wrong rate
def test_a_wrong_rate_is_the_error_with_what_the_channels_say(raw, capsys):
    """Physical fact: d'' at a stated rate f' is (f'/f)^2 times the true one.  ICA50 is 50 Hz; said
    to be 200 Hz its displacements' second derivative is 16 times its accelerations."""
    code, err = _cli(capsys, str(raw), "--rate-hz", "200", "--weights", WEIGHTS, "--weight-unit", "kN")
    assert code == 2
    assert "the sampling rate 200 Hz (--rate-hz) looks wrong" in err
    implied = float(err.split("a rate of about ")[1].split(" Hz")[0])
    assert implied == pytest.approx(50.0, rel=0.05)
    assert "0 of 7 consistency checks pass" in err and "--rate-hz" in err


def test_a_csv_whose_time_column_contradicts_its_channels_is_an_error(ica50, tmp_path):
    slow = dataclasses.replace(ica50, time=ica50.time * 4.0, consistency=None)  # 12.5 Hz
    path = write_run(slow, tmp_path / "slow.csv")
    with pytest.raises(MetadataError, match=r"sampling rate 12\.5 Hz .*looks wrong.*about 5\d(\.\d)? Hz"):
        read_run(path)


def test_a_rate_a_little_off_is_a_warning_not_an_error(ica50, tmp_path):
    """5 % off the true rate breaks a_i = d_i'' + a_g by about 10 %: a warning (below the 10 %
    rate tolerance of the error)."""
    off = dataclasses.replace(ica50, time=ica50.time * (50.0 / 47.5), consistency=None)
    path = write_run(off, tmp_path / "off.csv", float_format="%.12g")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConsistencyWarning)
        run = read_run(path)
    assert run.consistency.implied_rate_hz == pytest.approx(50.0, rel=0.02)
    assert not run.consistency.rate_looks_wrong()
    if not run.consistency.ok:  # the warning names the rate the data imply
        assert "sampling rate of about 5" in str(run.consistency)


def test_a_rate_that_disagrees_with_a_csv_time_column_is_an_error(ica50, tmp_path):
    path = write_run(ica50, tmp_path / "ica50.csv")
    with pytest.raises(ValueError, match=r"rate_hz = 200.*disagrees.*time_s.*50 Hz"):
        read_run(path, rate_hz=200)


# ------------------------------------------------------------------------------ level order
def test_roof_first_weights_read_base_first_are_flagged_on_stderr(raw, capsys):
    """The data's own order (a1 = roof) listed without --level-order: the story shears follow the
    drifts better with the masses reversed, and the command says so before anything else."""
    code, err = _cli(capsys, str(raw), "--rate-hz", "50", "--weights", WEIGHTS_ROOF_FIRST,
                     "--weight-unit", "kN", "--calibrate", "NOPE")
    assert code == 2  # NOPE: stops after reading
    warning = [ln for ln in err.splitlines() if "warning" in ln]
    assert len(warning) == 1 and "masses look listed in the opposite order" in warning[0]
    assert "--level-order roof-first" in warning[0] and "--weights" in warning[0]


def test_a_folder_whose_a1_is_the_base_slab_is_flagged_and_a1_base_reads_it(ica50, tmp_path):
    """Physical fact: the displacement relative to the table grows from the base slab (the isolator
    displacement) to the roof; read upside down it falls."""
    folder = _write_folder(ica50, tmp_path / "up", a1="base")
    with pytest.warns(LevelOrderWarning, match=r"upside down.*a1 = \"base\""):
        read_run(folder, rate_hz=50, weights=BNCS_WEIGHTS_KN)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = read_run(folder, rate_hz=50, weights=BNCS_WEIGHTS_KN, a1="base")
    np.testing.assert_allclose(run.disp, ica50.disp, rtol=1e-6, atol=1e-12)
    (folder / "run.toml").write_text('rate_hz = 50\n[levels]\na1 = "base"\nlevel_order = "roof-first"\n'
                                     f"weights = {list(BNCS_WEIGHTS_KN[::-1])}\nweight_unit = \"kN\"\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = read_run(folder)
    np.testing.assert_allclose(run.masses, ica50.masses, rtol=1e-9)


def test_csv_levels_labelled_upside_down_are_flagged(ica50, tmp_path):
    flipped = dataclasses.replace(ica50, accel=ica50.accel[:, ::-1], disp=ica50.disp[:, ::-1],
                                  masses=ica50.masses, consistency=None)
    path = write_run(flipped, tmp_path / "flipped.csv")
    with pytest.warns(LevelOrderWarning, match="upside down"):
        read_run(path)
    assert check_level_order(ica50) == []


@pytest.mark.parametrize("name", ["ICA50", "ICA100"])
def test_masses_in_the_right_order_raise_nothing_and_reversed_ones_a_warning(name):
    run = load_run(name)
    assert check_level_order(run) == []
    rev = dataclasses.replace(run, masses=run.masses[::-1].copy(), consistency=None)
    (msg,) = check_level_order(rev)
    assert "opposite order" in msg


# -------------------------------------------------------------- warnings reach the JSON and report
def test_reader_warnings_lead_the_notes_of_the_json(raw, capsys, tmp_path, monkeypatch):
    """A run read with a warning: the warning is printed on stderr and is the first note of the
    JSON (the pipeline is replaced by a stub: only the CLI's handling is under test)."""

    @dataclasses.dataclass(frozen=True)
    class Stub:
        notes: tuple
        report: object = dataclasses.field(
            default_factory=lambda: SimpleNamespace(skipped={}, budget_message=None))

        def as_dict(self):
            return {"notes": list(self.notes)}

    seen = {}

    def fake_gap(runs, **kw):
        seen["runs"] = runs
        return Stub(notes=("a pipeline note",))

    monkeypatch.setattr(st_cmd, "shake_table_gap", fake_gap)
    monkeypatch.setattr(st_cmd, "write_report", lambda res, out: Path(out) / "shake_table.md")
    code = cli.main(["shake-table", str(raw), "--rate-hz", "50", "--weights", WEIGHTS_ROOF_FIRST,
                     "--weight-unit", "kN", "--json", "--out", str(tmp_path / "o"), "--no-progress"])
    out, err = capsys.readouterr()
    assert code == 0
    notes = json.loads(out)["notes"]
    assert notes[0].startswith("reading: ") and "opposite order" in notes[0]
    assert notes[-1] == "a pipeline note"
    assert "opposite order" in err
    assert seen["runs"][0].masses[0] == pytest.approx(BNCS_WEIGHTS_KN[-1] / 9.81)


def test_consistency_failures_are_shown_too(ica50, tmp_path):
    disp = np.array(ica50.disp)
    disp[:, 2] = np.roll(disp[:, 2], 12)  # a 0.24 s timing error in one channel
    bad = dataclasses.replace(ica50, disp=disp, consistency=None)
    path = write_run(bad, tmp_path / "bad.csv")
    (run,), notes = _read(path)
    assert len(notes) == 1 and "floor3" in notes[0] and "\n" not in notes[0]
    assert not run.consistency.ok


def test_the_bundled_names_still_resolve(capsys):
    assert set(available_runs()) >= {"ICA50", "ICA100"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConsistencyWarning)
        (run,), _ = _read("ICA50")
    assert run.name == "ICA50"


def test_a_rate_option_that_contradicts_a_csv_time_column_names_the_option(capsys):
    code, err = _cli(capsys, "ICA50", "--rate-hz", "200")
    assert code == 2 and "--rate-hz = 200.0 Hz disagrees with its column 'time_s' (50 Hz)" in err
