"""Running the validation table: one diagnosis per case, in parallel, resumable, within a budget.

Every case (:class:`.cases.Case`) is made into its tests and diagnosed by
:func:`rrfrei.gap.diagnose_gap` (calibrate on protocol 1, hold out 2-4, the effect withheld).
Cases run in ``workers`` processes (:class:`concurrent.futures.ProcessPoolExecutor`, started by a
fork server where the platform has one: a fork of a process using OpenMP threads is unsafe),
with a tqdm bar, a wall-clock
budget for the whole table (cases not started when it runs out are listed as not run) and one for
each diagnosis, and a checkpoint: every finished case is appended to a JSON-lines file with the
settings it ran with, and a rerun with the same file and settings skips it.
"""

from __future__ import annotations

import json
import math
import os
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rrfrei.gap.validation.cases import FIXED, Case, make_case_tests

__all__ = ["Settings", "FULL", "REDUCED", "ValidationResult", "run_case", "run_table", "VERDICTS"]

VERDICTS = ("none", "unexplained", "incomplete")
"""Verdicts other than an effect's name."""


@dataclass(frozen=True)
class Settings:
    """How every case is diagnosed.

    Attributes
    ----------
    rate : sampling rate of the protocols [Hz] (protocol 1: 10 s cycles).
    draws : Laplace posterior draws per fit.
    combine : let the diagnosis add further effects after the first (the table scores the first).
    case_budget : wall-clock budget of one diagnosis [s] (None: none); a diagnosis that runs out
        is ``incomplete``.
    """

    rate: float = 5.0
    draws: int = 50
    combine: bool = False
    case_budget: float | None = 300.0

    def __post_init__(self) -> None:
        if not (isinstance(self.rate, (int, float)) and self.rate >= 2.0):
            raise ValueError(f"rate must be a sampling rate >= 2 Hz, got {self.rate!r}")
        if not (isinstance(self.draws, int) and self.draws >= 10):
            raise ValueError(f"draws must be an integer >= 10, got {self.draws!r}")
        if self.case_budget is not None and not self.case_budget > 0:
            raise ValueError(f"case_budget must be a number of seconds > 0 or None, got {self.case_budget!r}")

    @property
    def signature(self) -> str:
        """What a checkpoint line must match to be reused: the settings, a hash of the generator
        forms and cases (edited forms make new data) and one of the engine (a changed diagnosis
        gives new verdicts): never a stale row."""
        return (f"rate={self.rate:g}|draws={self.draws}|combine={int(self.combine)}|data={DATA_HASH}"
                f"|engine={ENGINE_HASH}")


def _source_hash(files) -> str:
    import hashlib

    h = hashlib.sha256()
    for f in sorted(files):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


_HERE = Path(__file__).parent
DATA_HASH = _source_hash([_HERE / "forms.py", _HERE / "cases.py"])
"""Hash of the generator forms' and cases' source as imported (a process keeps the code it loaded)."""
_PKG = _HERE.parents[1]
ENGINE_HASH = _source_hash([f for d in ("gap", "laws", "calibration") for f in (_PKG / d).rglob("*.py")
                            if _HERE not in f.parents] + [_PKG / "io.py"])
"""Hash of the diagnosis engine's source: rrfrei/gap (but this package), laws, calibration, io."""


FULL = Settings(rate=5.0, draws=50)
"""The table's settings: 5 Hz (50 samples per 10 s cycle of protocol 1) and 50 draws (on 26
cases, 10 Hz and 100 draws gave the same 26 verdicts at twice the time).  The 310 cases took
1,176 s of CPU (3.8 s per case, median 3.7 s, max 10.7 s), 13 minutes of wall time in 2
processes on the shared 2-core machine under a load of about 3 from other work, so about 10
minutes on 2 cores of its own (docs/gap/validation.md)."""
REDUCED = FULL
"""The settings of quick runs (the same: a quick run has fewer cases, not a coarser resolution)."""


def _shrink(before, after) -> float:
    try:
        b, a = float(before), float(after)
    except (TypeError, ValueError):
        return float("nan")
    return 1.0 - a / b if b > 0 and math.isfinite(a) else float("nan")


def run_case(case: Case, settings: Settings = FULL, deadline: float | None = None) -> dict:
    """Make and diagnose one case; the row of the table (never raises for a numerical failure:
    the verdict is then ``incomplete`` and ``note`` says why).

    ``deadline`` : wall-clock time (``time.time()``) after which the case is not started.
    """
    from rrfrei.budget import BudgetExceeded
    from rrfrei.errors import NUMERICAL_ERRORS
    from rrfrei.gap.diagnose import diagnose_gap

    t0 = time.perf_counter()
    c0 = time.process_time()
    row = {
        "key": case.key,
        "effect": case.effect,
        "form": case.form,
        "seed": case.seed,
        "base": case.base,
        "settings": settings.signature,
    }
    budget = settings.case_budget
    if deadline is not None:
        left = deadline - time.time()
        if left <= 0:
            return {**row, "verdict": "not run", "note": "table time budget reached"}
        budget = left if budget is None else min(budget, left)
    data = make_case_tests(case, rate=settings.rate)
    row.update(
        size=data.size,
        size_quantile=data.size_quantile,
        noise=data.noise_kind,
        noise_sd=data.noise_sd,
        effect_gap=data.effect_gap,
    )
    tests = data.tests
    try:
        rep = diagnose_gap(
            tests[0],
            case.base,
            holdout=tests[1:],
            fixed=FIXED,
            draws=settings.draws,
            seed=case.seed,
            combine=settings.combine,
            progress=False,
            time_budget=budget,
        )
    except (BudgetExceeded, *NUMERICAL_ERRORS) as exc:
        return {
            **row,
            "verdict": "incomplete",
            "note": f"{type(exc).__name__}: {exc}"[:300],
            "seconds": time.perf_counter() - t0,
            "cpu": time.process_time() - c0,
        }
    verdict = str(getattr(rep, "verdict", rep.diagnosis))
    b, f = rep.baseline[1], rep.final[1]
    named = verdict not in VERDICTS
    first = next((s for s in rep.ranking if s.effect == verdict), None)
    row.update(
        verdict=verdict,
        combination="+".join(rep.combination) or "none",
        gap_before=b.gap,
        gap_after=f.gap if named else b.gap,
        systematic_before=b.systematic,
        systematic_after=f.systematic if named else b.systematic,
        shrink=_shrink(b.systematic, first.holdout.systematic)
        if (named and first is not None)
        else float("nan"),
        variant=first.variant if (named and first is not None) else "",
        best=rep.ranking[0].effect if rep.ranking else "",
        best_shrink=_shrink(b.systematic, rep.ranking[0].holdout.systematic) if rep.ranking else float("nan"),
        seconds=time.perf_counter() - t0,
        cpu=time.process_time() - c0,
        note="",
    )
    return row


def _init_worker() -> None:
    """A pool worker: warnings off, and Numba's parallel kernels (the calibration's batched
    forces, :mod:`rrfrei.calibration._batch`) on one thread, since the table already runs one
    process per core.  The CMA-ES batches are small (a population of ~12 histories of ~600
    samples), so a second thread per process only contends: measured on the 2-core machine under
    load, the baseline's two global searches (:meth:`rrfrei.gap.isolator.IsolatorModel._base_start`)
    took 1.0 s of CPU and 1.0 s of wall time on one thread against 2.9 s and 2.2-2.4 s on two, with
    the same optimum (each history is computed alone: the thread count cannot change a force)."""
    import warnings

    import numba

    warnings.simplefilter("ignore")
    numba.set_num_threads(1)


def _read_checkpoint(path: Path, settings: Settings) -> dict[str, dict]:
    done: dict[str, dict] = {}
    if not path.is_file():
        return done
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut by an interrupted run
        if row.get("settings") == settings.signature and row.get("verdict") not in (None, "not run"):
            done[row["key"]] = row
    return done


def _clean(row: dict) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}


def run_table(
    case_list: list[Case],
    settings: Settings = FULL,
    *,
    workers: int = 2,
    time_budget: float | None = None,
    checkpoint: str | os.PathLike | None = None,
    progress: bool = True,
) -> ValidationResult:
    """Diagnose every case of ``case_list`` (see the module docstring).

    Parameters
    ----------
    case_list : the cases (:func:`rrfrei.gap.validation.cases`).
    settings : resolution, draws and per-diagnosis budget (:data:`FULL`, :data:`REDUCED`).
    workers : processes (1: in this process, no pool).
    time_budget : wall-clock budget of the whole table [s] (None: none); cases not started in
        time are rows with verdict ``not run``.
    checkpoint : JSON-lines file of finished cases, appended as they finish and read first.
    progress : tqdm bar on stderr.
    """
    from rrfrei.budget import progress as progress_bar

    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if time_budget is not None and not time_budget > 0:
        raise ValueError(f"time_budget must be a number of seconds > 0 or None, got {time_budget!r}")
    keys = [c.key for c in case_list]
    if len(set(keys)) != len(keys):
        raise ValueError("case_list repeats a case")
    t0 = time.perf_counter()
    deadline = None if time_budget is None else time.time() + float(time_budget)
    ck = Path(checkpoint) if checkpoint is not None else None
    done = _read_checkpoint(ck, settings) if ck is not None else {}
    rows = {k: v for k, v in done.items() if k in set(keys)}
    todo = [c for c in case_list if c.key not in rows]
    sink = None
    if ck is not None:
        ck.parent.mkdir(parents=True, exist_ok=True)
        sink = ck.open("a", encoding="utf-8")

    def finished(row: dict) -> None:
        rows[row["key"]] = row
        if sink is not None and row.get("verdict") != "not run":
            sink.write(json.dumps(_clean(row)) + "\n")
            sink.flush()
        bar.update()
        bar.set_postfix_str(f"{row['key']}: {row.get('verdict')}")

    bar = progress_bar(len(todo), "gap-validate", enabled=progress, unit="case")
    try:
        with bar:
            if workers == 1 or len(todo) <= 1:
                for c in todo:
                    finished(run_case(c, settings, deadline))
            else:
                import multiprocessing as mp

                # forkserver where there is one: fork() from a process whose Numba kernels already
                # run on GNU OpenMP threads kills the child ("fork() called from a process already
                # using GNU OpenMP, this is unsafe": the slow tier after other tests); the server is
                # a fresh process, and the workers load the compiled kernels from the cache
                method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
                with ProcessPoolExecutor(
                    max_workers=workers, mp_context=mp.get_context(method), initializer=_init_worker
                ) as pool:
                    pending = {pool.submit(run_case, c, settings, deadline) for c in todo}
                    while pending:
                        fin, pending = wait(pending, return_when=FIRST_COMPLETED)
                        for fut in fin:
                            finished(fut.result())
    finally:
        if sink is not None:
            sink.close()
    ordered = [rows[k] for k in keys if k in rows]
    return ValidationResult(pd.DataFrame(ordered), settings, time.perf_counter() - t0, len(done))


@dataclass(frozen=True)
class ValidationResult:
    """The table of a validation run and its summaries.

    ``cases`` has one row per case: ``key, effect, form, seed, base, size, size_quantile, noise,
    noise_sd, effect_gap, verdict, combination, gap_before, gap_after, systematic_before,
    systematic_after, shrink`` (held-out systematic-gap shrink of the named effect, NaN when none
    is named), ``variant`` (the variant that stood for the named effect, "" for its primary fit),
    ``best`` (top of the ranking), ``best_shrink``, ``seconds``, ``note``; plus
    ``case`` (= effect) and ``diagnosed`` (= verdict) for older callers.
    """

    cases: pd.DataFrame
    settings: Settings = FULL
    seconds: float = float("nan")
    reused: int = 0

    def __post_init__(self) -> None:
        df = self.cases
        if len(df):
            df["case"] = df["effect"]
            df["diagnosed"] = df["verdict"]

    # --- subsets ------------------------------------------------------------------------------
    @property
    def ran(self) -> pd.DataFrame:
        return self.cases[self.cases.verdict != "not run"] if len(self.cases) else self.cases

    @property
    def effect_cases(self) -> pd.DataFrame:
        r = self.ran
        return r[r.effect != "control"] if len(r) else r

    @property
    def control_cases(self) -> pd.DataFrame:
        r = self.ran
        return r[r.effect == "control"] if len(r) else r

    @property
    def effects(self) -> list[str]:
        return list(dict.fromkeys(self.effect_cases.effect)) if len(self.effect_cases) else []

    @property
    def not_run(self) -> int:
        return int((self.cases.verdict == "not run").sum()) if len(self.cases) else 0

    # --- summaries ----------------------------------------------------------------------------
    @property
    def confusion(self) -> pd.DataFrame:
        """Cases by true effect (rows, ``control`` last) and verdict (columns: every effect, then
        ``none``, ``unexplained``, ``incomplete``)."""
        r = self.ran
        rows = self.effects + (["control"] if len(self.control_cases) else [])
        extra = (
            [v for v in r.verdict.unique() if v not in self.effects and v not in VERDICTS] if len(r) else []
        )
        cols = self.effects + sorted(extra) + list(VERDICTS)
        if not len(r):
            return pd.DataFrame(0, index=rows, columns=cols)
        conf = pd.crosstab(r.effect, r.verdict).reindex(index=rows, columns=cols, fill_value=0)
        conf.index.name = "true"
        conf.columns.name = "verdict"
        return conf

    @property
    def accuracy(self) -> float:
        """Top-1 accuracy over every effect case (verdict = the true effect)."""
        e = self.effect_cases
        return float((e.effect == e.verdict).mean()) if len(e) else float("nan")

    def top1(self, by: str = "effect") -> pd.DataFrame:
        """Top-1 accuracy and miss rate per ``effect`` or per ``form`` (effect/form)."""
        e = self.effect_cases.copy()
        if not len(e):
            return pd.DataFrame(columns=["cases", "named", "top1", "miss_rate"])
        e["hit"] = e.effect == e.verdict
        key = ["effect"] if by == "effect" else ["effect", "form"]
        g = e.groupby(key, sort=False).hit
        out = pd.DataFrame({"cases": g.size(), "named": g.sum().astype(int), "top1": g.mean()})
        out["miss_rate"] = 1.0 - out.top1
        return out

    @property
    def false_alarms(self) -> int:
        """Controls on which an effect was named (``unexplained`` and ``none`` are not alarms)."""
        c = self.control_cases
        return int((~c.verdict.isin(VERDICTS)).sum()) if len(c) else 0

    @property
    def false_alarm_rate(self) -> float:
        c = self.control_cases
        return self.false_alarms / len(c) if len(c) else float("nan")

    @property
    def shrink_named(self) -> pd.Series:
        """Held-out systematic-gap shrink of every case where an effect was named."""
        r = self.ran
        if not len(r):
            return pd.Series(dtype=float)
        return r.loc[~r.verdict.isin(VERDICTS), "shrink"].astype(float)

    def goals(self) -> dict:
        """Issue 12's goals, each with its number and whether it is met."""
        per = self.top1("effect")
        s = self.shrink_named.dropna()
        return {
            "top1_per_effect_ge_95": {
                "value": {k: float(v) for k, v in per.top1.items()},
                "met": bool(len(per) and (per.top1 >= 0.95).all()),
                "missed_by": [k for k, v in per.top1.items() if v < 0.95],
            },
            "no_false_alarm": {"value": self.false_alarms, "met": self.false_alarms == 0},
            "shrink_ge_50_when_named": {
                "value": {
                    "median": float(s.median()) if len(s) else None,
                    "min": float(s.min()) if len(s) else None,
                    "below": int((s < 0.5).sum()),
                },
                "met": bool(len(s) and (s >= 0.5).all()),
            },
        }

    def as_dict(self) -> dict:
        def num(x):
            return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else x

        conf = self.confusion
        s = self.shrink_named.dropna()
        return {
            "settings": asdict(self.settings),
            "cases_total": int(len(self.cases)),
            "not_run": self.not_run,
            "reused_from_checkpoint": self.reused,
            "seconds": num(self.seconds),
            "accuracy": num(self.accuracy),
            "false_alarms": self.false_alarms,
            "false_alarm_rate": num(self.false_alarm_rate),
            "shrink_named": {
                "median": num(float(s.median())) if len(s) else None,
                "min": num(float(s.min())) if len(s) else None,
                "n": int(len(s)),
            },
            "goals": self.goals(),
            "top1_per_effect": {
                k: {"cases": int(r.cases), "named": int(r.named), "top1": float(r.top1)}
                for k, r in self.top1("effect").iterrows()
            },
            "top1_per_form": {
                "/".join(k): {"cases": int(r.cases), "named": int(r.named), "top1": float(r.top1)}
                for k, r in self.top1("form").iterrows()
            },
            "confusion": {str(k): {str(c): int(v) for c, v in row.items()} for k, row in conf.iterrows()},
            "cases": [
                _clean({k: (v.item() if isinstance(v, np.generic) else v) for k, v in row.items()})
                for row in self.cases.to_dict(orient="records")
            ],
        }
