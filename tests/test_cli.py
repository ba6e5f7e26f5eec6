"""CLI-wide behaviour, run as a user runs it (subprocesses):

* every command's ``--help`` shows an example;
* a user error (wrong path, malformed file, unknown law, unknown record, bad parameter) gives ONE
  line on stderr and exit status 2, never a traceback.

All subprocesses of this module run concurrently in one fixture (they are independent), which keeps
the module to a few seconds.  The help of every command is printed by one subprocess (each one a
fresh interpreter costs a few seconds of imports); ``rrfrei --help`` and every user error are
processes of their own, as a user runs them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pandas as pd
import pytest

from rrfrei.app.cli import COMMANDS

RRFREI = [sys.executable, "-m", "rrfrei.app"]
RUBBER = [sys.executable, "-m", "rubber"]

# command name as typed (module names use '_', command names '-')
COMMAND_NAMES = tuple(c.replace("_", "-") for c in COMMANDS)
RUBBER_COMMANDS = ("fit", "predict", "cases")


BAD_FILES = {
    "malformed.csv": "time_s,disp_mm,force_kN\n0.0,0.0,0.0\n0.05,abc,1.0\n0.10,0.2,\n",
    "posterior.nc": "this is not a netCDF file\n",
    "building.toml": "story_masses = [1.0, \n",
    "rubber_bad.csv": "time_s,stretch,stress_MPa\n0,1.0,0\n1,nan,0.1\n",
    "rubber_ok.csv": "time_s,stretch,stress_MPa\n0,1.0,0\n1,1.1,0.1\n2,1.2,0.2\n3,1.1,0.05\n",
    "params.json": "{not json",
}
"""Inputs a user could hand over (all bad but ``rubber_ok.csv``), by file name."""


def _files(root: Path, write: bool = True) -> dict[str, Path]:
    """:data:`BAD_FILES` below ``root`` (keyed by stem; written unless ``write`` is False), and
    paths that do not exist."""
    files = {Path(name).stem: root / name for name in BAD_FILES}
    if write:
        root.mkdir(parents=True, exist_ok=True)
        for name, text in BAD_FILES.items():
            (root / name).write_text(text)
    return {
        **files,
        "missing": root / "no_such_dir" / "p1.csv",
        "out": root / "out",
        "p1": root / "protocol1.csv",
    }


def _cases(f: dict[str, Path]) -> dict[str, tuple[list[str], str]]:
    """case id -> (argv, a word the one-line error must contain) for user errors (exit 2)."""
    out, missing, malformed, nc, toml = (str(f[k]) for k in ("out", "missing", "malformed", "posterior",
                                                             "building"))
    rubber_bad, rubber_ok, params_bad = str(f["rubber_bad"]), str(f["rubber_ok"]), str(f["params"])
    p1 = str(f["p1"])  # a valid test: only the argument under test is wrong
    c = {
        # calibrate
        "calibrate/wrong-path": (["calibrate", missing, "--law", "bouc_wen", "--out", out], "no_such_dir"),
        "calibrate/malformed": (["calibrate", malformed, "--law", "bouc_wen", "--out", out], "malformed"),
        "calibrate/unknown-law": (["calibrate", p1, "--law", "no_such_law", "--out", out], "no_such_law"),
        "calibrate/bad-noise": (["calibrate", p1, "--law", "bouc_wen", "--noise", "pink", "--out", out],
                                "pink"),
        "calibrate/bad-seed": (["calibrate", p1, "--law", "bouc_wen", "--seed", "x", "--out", out], "seed"),
        # compare
        "compare/wrong-path": (["compare", missing, "--laws", "all", "--out", out], "no_such_dir"),
        "compare/malformed": (["compare", malformed, "--laws", "all", "--out", out], "malformed"),
        "compare/unknown-law": (["compare", p1, "--laws", "bouc_wen,no_such_law", "--out", out],
                                "no_such_law"),
        # gap
        "gap/wrong-path": (["gap", missing, "--law", "bouc_wen", "--out", out], "no_such_dir"),
        "gap/malformed": (["gap", malformed, "--law", "bouc_wen", "--out", out], "malformed"),
        "gap/unknown-law": (["gap", p1, "--law", "no_such_law", "--out", out], "no_such_law"),
        "gap/wrong-holdout": (["gap", p1, "--law", "bouc_wen", "--holdout", missing, "--out", out],
                              "no_such_dir"),
        # gap-validate
        "gap-validate/bad-seeds": (["gap-validate", "--seeds", "0", "--out", out], "seeds"),
        # propagate
        "propagate/wrong-path": (["propagate", "--posterior", missing, "--building", "five_story",
                                  "--records", "elcentro", "--out", out], "no_such_dir"),
        "propagate/malformed": (["propagate", "--posterior", nc, "--building", "five_story",
                                 "--records", "elcentro", "--out", out], "posterior.nc"),
        "propagate/bad-building": (["propagate", "--posterior", nc, "--building", toml,
                                    "--records", "elcentro", "--out", out], "building.toml"),
        "propagate/unknown-building": (["propagate", "--posterior", nc, "--building", "no_such_building",
                                        "--records", "elcentro", "--out", out], "no_such_building"),
        "propagate/bad-samples": (["propagate", "--posterior", nc, "--building", "five_story",
                                   "--records", "elcentro", "--samples", "0", "--out", out], "samples"),
        # demo
        "demo/bad-seed": (["demo", "--seed", "-1", "--out", out], "seed"),
        "demo/out-is-a-file": (["demo", "--out", malformed, "--quick", "--no-progress"], "malformed.csv"),
    }
    c = {k: ([*RRFREI, *argv], expect) for k, (argv, expect) in c.items()}
    c.update({
        "rubber-fit/wrong-path": ([*RUBBER, "fit", missing, "--out", out], "no_such_dir"),
        "rubber-fit/malformed": ([*RUBBER, "fit", rubber_bad, "--out", out], "rubber_bad.csv"),
        "rubber-fit/bad-bounds": ([*RUBBER, "fit", rubber_ok, "--bounds", missing, "--out", out],
                                  "no_such_dir"),
        "rubber-predict/malformed-params": ([*RUBBER, "predict", "--params", params_bad, rubber_bad],
                                            "params.json"),
    })
    return c


def _run(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(argv, capture_output=True, text=True, timeout=300, cwd=cwd, env=env)


HELPS = '''
import contextlib, io, json, sys
from rrfrei.app.cli import main as rrfrei_main
from rubber.__main__ import main as rubber_main

out = {}
for key, prog, argv in json.loads(sys.argv[1]):
    buf, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(err):
            code = {"rrfrei": rrfrei_main, "rubber": rubber_main}[prog]([*argv, "--help"])
    except SystemExit as exc:
        code = 0 if exc.code is None else exc.code
    out[key] = [code, buf.getvalue(), err.getvalue()]
print(json.dumps(out))
'''
"""Prints ``{key: [exit status, stdout, stderr]}`` of ``PROG ARGV --help`` for each (key, prog, argv)."""


def _helps(cwd: Path) -> dict[str, subprocess.CompletedProcess]:
    """Every command's ``--help`` (but ``rrfrei --help``), from one subprocess."""
    jobs = [(f"help/{name}", "rrfrei", [name]) for name in COMMAND_NAMES]
    jobs += [(f"help/rubber-{name}", "rubber", [name]) for name in RUBBER_COMMANDS]
    proc = _run([sys.executable, "-c", HELPS, json.dumps(jobs)], cwd)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads(proc.stdout)
    return {key: subprocess.CompletedProcess(argv, *res[key]) for key, _, argv in jobs}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli")
    files = _files(root)
    # the bundled protocol-1 test as a plain file, so that only the argument under test is wrong
    from rrfrei.io import load_test

    files["p1"].write_text(pd.DataFrame({"time_s": (t := load_test("protocol1")).time,
                                         "disp_mm": 1e3 * t.disp, "force_kN": t.force}).to_csv(index=False))
    jobs = {"help/rrfrei": [*RRFREI, "--help"]}
    jobs.update({k: argv for k, (argv, _) in _cases(files).items()})
    with ThreadPoolExecutor(max_workers=4) as pool:
        helps = pool.submit(_helps, root)
        futures = {k: pool.submit(_run, argv, root) for k, argv in jobs.items()}
        return {**helps.result(), **{k: fut.result() for k, fut in futures.items()}}


HELP_IDS = ["rrfrei", *COMMAND_NAMES, *(f"rubber-{n}" for n in RUBBER_COMMANDS)]


@pytest.mark.parametrize("name", HELP_IDS)
def test_every_command_help_shows_an_example(runs, name):
    proc = runs[f"help/{name}"]
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Example" in proc.stdout or "example" in proc.stdout, proc.stdout[-2000:]
    cmd = "rrfrei" if name == "rrfrei" else name.replace("rubber-", "")
    example_lines = [ln for ln in proc.stdout.splitlines()
                     if cmd in ln and ("rrfrei" in ln or "rubber" in ln)]
    assert example_lines, f"no example command line in the help of {name}"


def _dummy() -> dict[str, Path]:
    """Paths with the real file names (the ids and expected words do not depend on the folder)."""
    return _files(Path("/nonexistent"), write=False)


def _error_ids() -> list[str]:
    return list(_cases(_dummy()))


@pytest.mark.parametrize("case", _error_ids())
def test_user_error_gives_one_line_on_stderr_and_exit_2(runs, case):
    proc = runs[case]
    err = proc.stderr.strip()
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert proc.returncode == 2, f"exit {proc.returncode}; stderr: {proc.stderr[-2000:]}"
    assert err and "\n" not in err, f"expected one line on stderr, got:\n{proc.stderr}"
    expect = _cases(_dummy())[case][1]
    assert expect in err, f"the error should name {expect!r}: {err}"



def _raiser(kind: str, text: str):
    import numpy as np

    from rrfrei.errors import NumericalFailure

    exc = {"linalg": np.linalg.LinAlgError, "numerical": NumericalFailure,
           "zerodiv": ZeroDivisionError, "value": ValueError}[kind](text)

    def boom(args):
        raise exc

    return boom


@pytest.mark.parametrize(
    "kind, text, code",
    [
        ("linalg", "Singular matrix", 1),  # LinAlgError is a ValueError subclass, yet numerical
        ("numerical", "law failed at sample 8590", 1),
        ("zerodiv", "float division by zero", 1),
        ("value", "disp_mm: expected a number", 2),
    ],
)
def test_a_numerical_failure_exits_1_and_a_user_error_exits_2(monkeypatch, capsys, kind, text, code):
    from rrfrei.app import cli

    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda *_: parser)
    parser._subparsers._group_actions[0].choices["calibrate"].set_defaults(func=_raiser(kind, text))
    rc = cli.main(["calibrate", "protocol1", "--law", "linear", "--out", "unused"])
    err = capsys.readouterr().err
    assert rc == code
    assert len(err.strip().splitlines()) == 1 and text in err
    assert ("numerical failure" in err) == (code == 1)


def _touch(path):
    Path(path).write_text("drawn")


def _fail(path):
    raise OSError(f"cannot draw {path}")


def test_the_calibrate_figures_worker_finishes_before_the_command_and_its_failure_is_not_silent(tmp_path):
    """The figures are drawn in a second process while the command writes its files: the block
    waits for it, and a failure there becomes an error of the command, not a missing file."""
    from rrfrei.app.commands.calibrate import _in_parallel

    with _in_parallel(_touch, tmp_path / "fig.png"):
        pass
    assert (tmp_path / "fig.png").read_text() == "drawn"
    with pytest.raises(RuntimeError, match="_fail failed in its worker process"):
        with _in_parallel(_fail, tmp_path / "x.png"):
            pass
    with pytest.raises(ValueError, match="the block's own error"):  # the block's error wins
        with _in_parallel(_touch, tmp_path / "y.png"):
            raise ValueError("the block's own error")
