"""The :class:`Calibration` result: InferenceData, MAP, summary table, draws, netCDF round trip.

For a dense record (likelihood on every ``stride``-th sample, :mod:`.likelihood`) the
``log_likelihood`` and ``posterior_predictive`` groups hold those samples only (their
``sample`` coordinate is the sample index in the test), in float32, for at most
:data:`MAX_DRAWS_DENSE` draws; ``observed_data`` and ``constant_data`` keep the whole test.

File size (issue 16: at most 10 MB per posterior): the stored draws are capped so that the
pointwise log-likelihood holds at most :data:`MAX_LOGLIK_VALUES` values (:func:`draws_cap`), and
:meth:`Calibration.to_netcdf` writes the ``log_likelihood`` and ``posterior_predictive`` groups
in float32 (7 significant digits, far below the Monte Carlo error of PSIS-LOO and of the
predictive bands; the in-memory result keeps float64).  A 2,401-sample test: 624 draws x 2,401
values x 4 bytes = 6.0 MB, plus ~96 predictive draws x 2 x 2,401 x 4 bytes = 1.8 MB.

The ``posterior`` group holds the sampled quantities (free law parameters, ``sigma`` [kN] and,
for AR(1) noise, ``rho``) with the walkers as chains.  Its attributes hold everything needed to
rebuild the result from the netCDF file alone: the law name, the fixed (geometry and default)
values, the noise model, the MAP, the calibrated displacement range and the diagnostics.  The
test itself is in ``observed_data`` (force) and ``constant_data`` (displacement, time).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rrfrei.calibration.noise import NoiseModel, noise_model, simulate_noise
from rrfrei.io import ShearTest
from rrfrei.laws import LawSpec, get

__all__ = ["Calibration", "load_arviz", "arviz_numpy", "posterior_draws", "loglik_pointwise", "build_idata",
           "summary_table", "simulate_noise", "draws_cap"]

MAX_DRAWS = 1000
"""Posterior draws kept (walkers x draws) after burn-in and thinning."""
PREDICTIVE_DRAWS = 100
"""Draws (spread over the walkers) whose force histories are stored as posterior_predictive."""
MAX_LOGLIK_VALUES = 1_500_000
"""Most values of the stored pointwise log-likelihood (draws x likelihood samples): 6 MB in
float32 (:func:`draws_cap`)."""
MAX_DRAWS_DENSE = 500
"""Posterior draws kept for a dense record (likelihood on a subsample, see
:mod:`.likelihood`): with <= 2,000 likelihood samples stored in float32, the pointwise
log-likelihood then takes <= 4 MB and the whole netCDF file stays under 10 MB."""
PREDICTIVE_DRAWS_DENSE = 100
"""Posterior-predictive draws stored for a dense record (at the likelihood's samples, float32)."""


def draws_cap(n_like: int, dense: bool, walkers: int) -> int:
    """Most posterior draws stored for a likelihood on ``n_like`` samples.

    ``min(MAX_DRAWS_DENSE if dense else MAX_DRAWS, MAX_LOGLIK_VALUES // n_like)``, and never fewer
    than two per walker (the draws are walkers x draws per walker); e.g. 624 for 2,401 samples,
    500 for a dense record's <= 2,000 likelihood samples.
    """
    base = MAX_DRAWS_DENSE if dense else MAX_DRAWS
    return int(max(2 * walkers, min(base, MAX_LOGLIK_VALUES // max(int(n_like), 1))))


FLOAT32_GROUPS = ("log_likelihood", "posterior_predictive")
"""InferenceData groups :meth:`Calibration.to_netcdf` writes in float32."""


def load_arviz():
    """The ``arviz`` module, imported with its FutureWarnings silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az
    return az


@contextmanager
def arviz_numpy():
    """``arviz`` (:func:`load_arviz`) with its Numba paths off inside the block (restored after).

    arviz jits a few helpers of its statistics (the variance in ``rhat`` and ``ess``, a square
    root in ``mcse``) without a cache, so every process compiles them again, which takes longer
    than the ESS, R-hat and PSIS-LOO of a calibration's draws take with NumPy.  The NumPy paths
    compute the same quantities (``np.var`` in place of a one-pass sum of squares).
    """
    az = load_arviz()
    flag = az.Numba.numba_flag
    az.Numba.numba_flag = False
    try:
        yield az
    finally:
        az.Numba.numba_flag = flag


@dataclass(frozen=True, eq=False)
class Calibration:
    """Posterior of a law's parameters given a shear test.

    Attributes
    ----------
    law : law name (possibly augmented, ``"bouc_wen+rate"``).
    spec : its :class:`~rrfrei.laws.LawSpec`.
    test : the :class:`~rrfrei.io.ShearTest` calibrated on.
    idata : arviz InferenceData (posterior, log_likelihood (pointwise, per sample), posterior
        predictive for a thinned set of draws, observed_data, constant_data, sample_stats).
    map : highest posterior density point found: free law parameters, ``sigma`` [kN] (, ``rho``).
    sigma : MAP noise standard deviation [kN] (innovation sd for AR(1)).
    summary : DataFrame indexed by sampled quantity: unit, mean, MAP, sd, 2.5%, 97.5%, ESS, R-hat.
    converged : the convergence rule holds (:data:`rrfrei.calibration.sampler.CONVERGENCE_RULE`:
        bulk and tail ESS >= 400 and R-hat < 1.05 on the stored draws, from a chain >= 10 stable
        autocorrelation times long); the run stopped by it, or met it at its end.
    fixed : values held fixed (geometry, optional parameters at their defaults, user ``fixed=``).
    noise : "iid" or "ar1".
    diagnostics : acceptance, tau, ESS, R-hat, steps, walkers, burn, thin, evaluations, seconds, note,
        stopped_by, max_steps, time_budget [s], resumed_steps, points, likelihood_points,
        likelihood_stride, stored_draws, max_draws.
    stopped_by : (property) why sampling stopped: "converged", "steps", "max_steps", "time_budget".
    """

    law: str
    spec: LawSpec
    test: ShearTest
    idata: Any
    map: dict[str, float]
    sigma: float
    summary: pd.DataFrame
    converged: bool
    fixed: dict[str, float] = field(default_factory=dict)
    noise: str = "iid"
    diagnostics: dict[str, Any] = field(default_factory=dict)

    @property
    def stopped_by(self) -> str | None:
        """Why sampling stopped: "converged", "steps", "max_steps" or "time_budget" (None: older file)."""
        return self.diagnostics.get("stopped_by")

    # --- parameters -----------------------------------------------------------------------
    @property
    def free(self) -> tuple[str, ...]:
        return tuple(json.loads(self.idata.posterior.attrs["free"]))

    @property
    def sampled(self) -> tuple[str, ...]:
        """Free law parameters then the noise parameters (the posterior's variables)."""
        return self.free + noise_model(self.noise).params

    def theta(self) -> np.ndarray:
        """(draws, sampled) matrix of all stored posterior draws (chains stacked)."""
        post = self.idata.posterior
        return np.column_stack([post[n].values.reshape(-1) for n in self.sampled])

    def map_params(self) -> dict[str, float]:
        """Full law parameter set (free at MAP + fixed) by name, ready for ``spec.pack``."""
        return _full_dict(self.spec, self.fixed, {k: self.map[k] for k in self.free})

    def draws(self, n: int | None = None, seed: int = 0, *, noise: bool = False) -> pd.DataFrame:
        """``n`` posterior draws (all when None) of FULL law parameter sets.

        Columns are the law's parameter names (free + fixed/geometry + defaults), in kernel order,
        then ``sigma`` (, ``rho``) when ``noise`` is True.  ``df.attrs`` holds ``law`` and ``noise``.
        """
        th = self.theta()
        idx = _choose(th.shape[0], n, seed)
        th = th[idx]
        cols = {}
        k = len(self.free)
        for p in self.spec.params:
            if p.name in self.free:
                cols[p.name] = th[:, self.free.index(p.name)]
            else:
                cols[p.name] = np.full(th.shape[0], self.fixed[p.name], dtype=float)
        if noise:
            for j, name in enumerate(self.sampled[k:]):
                cols[name] = th[:, k + j]
        df = pd.DataFrame(cols)
        df.attrs["law"] = self.law
        df.attrs["noise"] = self.noise
        df.attrs["disp_min_m"] = float(self.test.disp.min())
        df.attrs["disp_max_m"] = float(self.test.disp.max())
        return df

    # --- output -------------------------------------------------------------------------
    def to_netcdf(self, path: str | Path) -> Path:
        """Write the InferenceData (with everything needed by :meth:`from_netcdf`); the groups
        of :data:`FLOAT32_GROUPS` in float32 (see the module docstring)."""
        az = load_arviz()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        groups = {}
        for g in self.idata.groups():
            ds = self.idata[g]
            if g in FLOAT32_GROUPS:
                ds = ds.astype(np.float32, keep_attrs=True)
            groups[g] = ds
        az.InferenceData(**groups).to_netcdf(str(path))
        return path

    @classmethod
    def from_netcdf(cls, path: str | Path) -> Calibration:
        """Rebuild a calibration from a file written by :meth:`to_netcdf`."""
        az = load_arviz()
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(2, "No such file", str(path))
        idata = az.from_netcdf(str(path))
        return cls.from_idata(idata)

    @classmethod
    def from_idata(cls, idata, *, spec: LawSpec | None = None,
                   summary: pd.DataFrame | None = None) -> Calibration:
        """Rebuild a calibration from an InferenceData written by :func:`rrfrei.calibrate`.

        ``spec`` (the law named in the attributes, already resolved) and ``summary`` (its
        :func:`summary_table`, already computed) spare :func:`rrfrei.calibrate` a second lookup
        and a second pass of arviz' ESS and R-hat; by default both come from ``idata``.
        """
        if "posterior" not in idata.groups() or "law" not in idata.posterior.attrs:
            raise ValueError("this InferenceData was not written by rrfrei.calibrate (no law in attrs)")
        a = idata.posterior.attrs
        if spec is None:
            spec = get(str(a["law"]))
        elif spec.name != str(a["law"]):
            raise ValueError(f"spec = {spec.name!r}: expected the law of the InferenceData, {a['law']!r}")
        cd = idata.constant_data
        test = ShearTest(
            name=str(a["test_name"]),
            time=np.asarray(cd["time"].values, dtype=float),
            disp=np.asarray(cd["disp"].values, dtype=float),
            force=np.asarray(idata.observed_data["force"].values, dtype=float),
            has_time=bool(int(a["test_has_time"])),
            vertical_load=None if float(a["test_vertical_load"]) != float(a["test_vertical_load"])
            else float(a["test_vertical_load"]),
            geometry=json.loads(a["test_geometry"]),
            source=str(a["test_source"]),
        )
        mp = json.loads(a["map"])
        diag = json.loads(a["diagnostics"])
        return cls(
            law=spec.name, spec=spec, test=test, idata=idata, map=mp, sigma=float(mp["sigma"]),
            summary=summary if summary is not None else summary_table(
                idata, spec, mp, tuple(json.loads(a["free"])), str(a["noise"])),
            converged=bool(int(a["converged"])), fixed=json.loads(a["fixed"]), noise=str(a["noise"]),
            diagnostics=diag,
        )

    def opensees_command(self, tag: int = 1, i_node: int = 1, j_node: int = 2) -> str:
        """The openseespy call creating this law's element at the MAP (see :func:`opensees_command`)."""
        if not self.spec.opensees_element:
            raise ValueError(f"law {self.law!r} has no OpenSees element")
        return opensees_command(self.spec, self.map_params(), tag, i_node, j_node) + (
            f"  # {self.law} MAP, units kN, m, s")

    def predict(self, test: ShearTest | None = None, **kwargs):
        """Posterior predictive check on ``test`` (default: the calibration test); see checks.predict."""
        from rrfrei.calibration.checks import predict

        return predict(self, self.test if test is None else test, **kwargs)

    def __repr__(self) -> str:
        mp = ", ".join(f"{k}={v:.4g}" for k, v in self.map.items())
        return (f"Calibration(law={self.law!r}, test={self.test.name!r}, noise={self.noise!r}, "
                f"converged={self.converged}, map={{{mp}}})")


# ---------------------------------------------------------------------------------------------
# export to OpenSees
# ---------------------------------------------------------------------------------------------
#: Orientation of the exported elements: 2-D, local x (axial) along global Y and local y
#: (shear) along global +X; 3-D, local x along global Z and local y along global +X.
EXPORT_ORIENT = {2: (0.0, 1.0, 0.0, 1.0, 0.0, 0.0), 3: (0.0, 0.0, 1.0, 1.0, 0.0, 0.0)}


def opensees_command(spec: LawSpec, params: Mapping[str, float], tag: int = 1, i_node: int = 1,
                     j_node: int = 2) -> str:
    """The ``ops.element(...)`` call that builds law ``spec`` at ``params`` in openseespy 3.7.1.

    The element and its arguments are the law's (``LawSpec.opensees``,
    :meth:`~rrfrei.laws.LawSpec.opensees_args`).  Numbers are written with ``repr`` (full
    precision: the element reproduces :func:`rrfrei.simulate_force` to rounding).  Models and
    orientation (:data:`EXPORT_ORIENT`):

    - ``plasticity`` / ``bouc_wen``: 2-D model (``-ndm 2 -ndf 3``), zero-length element; axial and
      moment materials are tags 1 and 2 (``-P 1 -Mz 2``, the user's); ``-orient 0 1 0 1 0 0``
      puts local x (axial) along global Y and local y (shear) along global +X.
    - ``elastomeric_x`` / ``HDR``: 3-D only in OpenSees (``-ndm 3 -ndf 6``); all positional
      arguments are given (ElastomericX 29, HDR 32, as ``OPS_ElastomericX`` / ``OPS_HDR`` read
      them), the vertical ones at fixed values (:data:`rrfrei.laws.registry.OPENSEES_VERTICAL`;
      HDR's geometry, vertical terms only: :data:`rrfrei.laws.hdr.OPENSEES_GEOMETRY`);
      orientation ``0 0 1 1 0 0`` (local x along global Z, shear along global +X).
    """
    if spec.opensees is None:
        raise ValueError(f"law {spec.name!r} has no OpenSees element export")
    ndm = min(spec.opensees.dims)
    args = spec.opensees_args({k: float(v) for k, v in params.items()}, ndm=ndm,
                              orient=EXPORT_ORIENT[ndm])
    text = ", ".join(repr(a) if isinstance(a, str) else repr(float(a)) if isinstance(a, float) else str(a)
                     for a in args)
    return f"ops.element({spec.opensees_element!r}, {int(tag)}, {int(i_node)}, {int(j_node)}, {text})"


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _choose(total: int, n: int | None, seed: int) -> np.ndarray:
    if n is None:
        return np.arange(total)
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    rng = np.random.default_rng(seed)
    return rng.choice(total, size=int(n), replace=n > total)


def _full_dict(spec: LawSpec, fixed: Mapping[str, float], free: Mapping[str, float]) -> dict[str, float]:
    out = {}
    for p in spec.params:
        out[p.name] = float(free[p.name]) if p.name in free else float(fixed[p.name])
    return out


def summary_table(idata, spec: LawSpec, mp: Mapping[str, float], free: tuple[str, ...],
                  noise: str | NoiseModel) -> pd.DataFrame:
    """The :attr:`Calibration.summary` of a posterior: unit, mean, MAP, sd, 2.5 %, 97.5 %, bulk
    ESS and R-hat (arviz) per sampled quantity."""
    nm = noise_model(noise)
    names = list(free) + list(nm.params)
    post = idata.posterior
    with warnings.catch_warnings(), arviz_numpy() as az:
        warnings.simplefilter("ignore")
        ess = az.ess(idata, var_names=names, method="bulk")
        rhat = az.rhat(idata, var_names=names)
    rows = []
    for n in names:
        x = post[n].values.reshape(-1)
        unit = spec.param(n).unit if n in free else nm.units[nm.params.index(n)]
        rows.append({
            "parameter": n, "unit": unit, "mean": float(np.mean(x)), "MAP": float(mp[n]),
            "sd": float(np.std(x, ddof=1)) if x.size > 1 else float("nan"),
            "2.5%": float(np.quantile(x, 0.025)), "97.5%": float(np.quantile(x, 0.975)),
            "ESS": float(ess[n].values), "R-hat": float(rhat[n].values),
        })
    return pd.DataFrame(rows).set_index("parameter")


def build_idata(problem, chain, logp, *, burn: int, thin: int, theta_map, fixed, diagnostics, seed: int):
    """InferenceData from the kept chain (steps, walkers, ndim) (see the module docstring)."""
    import xarray as xr

    az = load_arviz()
    kept = chain[burn::thin]  # (draws, walkers, ndim)
    lp = logp[burn::thin]
    nd, nw, ndim = kept.shape
    names = problem.names
    posterior = {n: kept[:, :, j].T for j, n in enumerate(names)}  # (chain, draw)
    flat = kept.transpose(1, 0, 2).reshape(-1, ndim)  # chain-major, matches (chain, draw) order
    P = problem.full_params(flat)
    idx = problem.lik_idx
    sub = bool(problem.subsampled)
    F = np.empty((P.shape[0], idx.size))  # model forces at the likelihood's samples
    status = np.zeros(P.shape[0], dtype=np.int64)
    for b in range(0, P.shape[0], 128):  # batches: a dense record's full histories are large
        Fb, sb = problem.forces(P[b: b + 128])
        F[b: b + 128] = problem.at_points(Fb)
        status[b: b + 128] = sb
    sigma, rho = problem.noise_params(flat)
    ll = problem.pointwise(F, flat)
    ll[status != 0] = -np.inf
    store = np.float32 if sub else np.float64
    test = problem.test
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "more chains than draws": walkers are chains
        idata = _from_dict(az, posterior, None if sub else ll, nw, nd, lp, test, problem.n_points)
    if sub:
        idata.add_groups({"log_likelihood": xr.Dataset(
            {"force": (("chain", "draw", "sample"), ll.reshape(nw, nd, -1).astype(store))},
            coords={"chain": np.arange(nw), "draw": np.arange(nd), "sample": idx})})

    # posterior predictive on a thinned subset of draws (same chain/draw labels as the posterior)
    per_chain = max(1, (PREDICTIVE_DRAWS_DENSE if sub else PREDICTIVE_DRAWS) // nw)
    didx = np.unique(np.linspace(0, nd - 1, min(per_chain, nd)).round().astype(int))
    Fm = F.reshape(nw, nd, -1)[:, didx, :]
    rng = np.random.default_rng(seed + 7)
    sig = sigma.reshape(nw, nd)[:, didx]
    rh = None if rho is None else rho.reshape(nw, nd)[:, didx]
    noise = simulate_noise(rng, sig, rh, Fm.shape[-1])
    pp = xr.Dataset(
        {"force": (("chain", "draw", "sample"), (Fm + noise).astype(store)),
         "force_model": (("chain", "draw", "sample"), Fm.astype(store))},
        coords={"chain": np.arange(nw), "draw": didx, "sample": idx},
    )
    idata.add_groups({"posterior_predictive": pp})
    a = idata.posterior.attrs
    a["law"] = problem.spec.name
    a["free"] = json.dumps(list(problem.free))
    a["fixed"] = json.dumps({k: float(v) for k, v in fixed.items()})
    a["noise"] = problem.noise.name
    a["priors"] = json.dumps({k: [p.kind, p.a, p.b] for k, p in problem.priors.items()})
    a["disp_min_m"] = float(test.disp.min())
    a["disp_max_m"] = float(test.disp.max())
    a["test_name"] = test.name
    a["test_source"] = test.source
    a["test_has_time"] = int(test.has_time)
    a["test_vertical_load"] = float("nan") if test.vertical_load is None else float(test.vertical_load)
    a["test_geometry"] = json.dumps(test.geometry)
    a["map"] = json.dumps({n: float(x) for n, x in zip(names, theta_map)})
    a["diagnostics"] = json.dumps(diagnostics)
    a["converged"] = int(bool(diagnostics.get("converged", False)))
    a["burn"] = int(burn)
    a["thin"] = int(thin)
    return idata


def _from_dict(az, posterior, ll, nw, nd, lp, test, n_points):
    return az.from_dict(
        posterior=posterior,
        log_likelihood=None if ll is None else {"force": ll.reshape(nw, nd, -1)},
        observed_data={"force": np.asarray(test.force)},
        constant_data={"disp": np.asarray(test.disp), "time": np.asarray(test.time)},
        sample_stats={"lp": lp.T},
        dims={"force": ["sample"], "disp": ["sample"], "time": ["sample"]},
        coords={"sample": np.arange(n_points)},
    )


# ---------------------------------------------------------------------------------------------
# public helpers for other workflows (gap diagnosis, propagation)
# ---------------------------------------------------------------------------------------------
def posterior_draws(source, n: int | None = None, seed: int = 0) -> tuple[str, pd.DataFrame]:
    """``(law_name, DataFrame of n FULL parameter sets)`` from any posterior source.

    ``source`` is a :class:`Calibration`, an arviz InferenceData written by :func:`calibrate`, a
    netCDF path, or a DataFrame of draws whose law is in ``df.attrs["law"]`` (then its rows are
    resampled with replacement when ``n`` exceeds them).  Columns: the law's parameters in kernel
    order, plus ``sigma`` (, ``rho``) when known.
    """
    if isinstance(source, pd.DataFrame):
        law = source.attrs.get("law")
        if not law:
            raise ValueError('a DataFrame of draws must name its law in df.attrs["law"]')
        spec = get(law)
        missing = [p.name for p in spec.params if p.name not in source.columns and not p.optional]
        if missing:
            raise ValueError(f"draws for law {law!r} lack column(s) {', '.join(missing)}")
        idx = _choose(len(source), n, seed)
        df = source.iloc[idx].reset_index(drop=True)
        df.attrs = dict(source.attrs)
        return spec.name, df
    cal = _as_calibration(source)
    return cal.law, cal.draws(n, seed, noise=True)


def _as_calibration(source) -> Calibration:
    if isinstance(source, Calibration):
        return source
    if isinstance(source, (str, Path)):
        return Calibration.from_netcdf(source)
    if hasattr(source, "groups") and hasattr(source, "posterior"):
        return Calibration.from_idata(source)
    raise ValueError(
        f"expected a Calibration, InferenceData, netCDF path or DataFrame of draws; got "
        f"{type(source).__name__}"
    )


def loglik_pointwise(source, test: ShearTest, *, n: int | None = None, seed: int = 0) -> np.ndarray:
    """(draws, points) pointwise log-likelihood of ``test`` under posterior draws.

    ``source`` is a Calibration / InferenceData / netCDF path (all stored draws, or ``n`` of them),
    or a ``(law, DataFrame)`` pair / DataFrame with ``attrs["law"]`` whose columns include
    ``sigma`` (and ``rho`` for AR(1) noise: the noise model is AR(1) exactly when ``rho`` is a
    column).  Failing parameter sets give ``-inf`` rows.
    """
    from rrfrei.calibration.likelihood import law_forces

    if isinstance(source, tuple) and len(source) == 2:
        law, df = source
        df = df.copy()
        df.attrs["law"] = law if isinstance(law, str) else get(law).name
        source = df
    if isinstance(source, pd.DataFrame):
        law, df = posterior_draws(source, n, seed)
        if "sigma" not in df.columns:
            raise ValueError("draws need a 'sigma' column [kN] to evaluate a likelihood")
        spec = get(law)
    else:
        cal = _as_calibration(source)
        spec, df = cal.spec, cal.draws(n, seed, noise=True)
    noise = noise_model("ar1" if "rho" in df.columns else "iid")
    P = np.ascontiguousarray(
        np.column_stack([df[p.name].to_numpy(float) if p.name in df.columns else np.full(len(df), p.default)
                         for p in spec.params])
    )
    F, status = law_forces(spec, P, test)
    resid = np.asarray(test.force)[None, :] - F
    ll = noise.pointwise(resid, df[list(noise.params)].to_numpy(float))
    ll[status != 0] = -np.inf
    return ll
