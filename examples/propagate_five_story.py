"""Design check of the 5-story example building on a calibrated isolator posterior.

Run:  python examples/propagate_five_story.py [OUT_DIR]   (a few minutes on 2 cores)

1. calibrate the building's isolator law on the bundled (SYNTHETIC) RR-FREI test, protocol 1;
2. run 100 posterior draws through the building under five bundled records at three intensities;
3. print the demands, how much of their scatter comes from the isolator parameters, the chance of
   exceeding the tested isolator displacement and a 0.5 % drift, and the fragility curves;
4. save the figures and the tidy table (one row per draw x record x scale) in OUT_DIR.

The results are stored chunk by chunk in OUT_DIR/store: interrupt the script and run it again to
resume where it stopped.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import structures  # noqa: E402
from rrfrei.calibration import calibrate  # noqa: E402
from rrfrei.io import load_test  # noqa: E402
from structures.propagation.propagate import propagate  # noqa: E402

out = Path(sys.argv[1] if len(sys.argv) > 1 else "propagate_five_story")
out.mkdir(parents=True, exist_ok=True)

# The example building (structures/building/buildings/five_story.toml): five stories on isolators whose law
# and geometry are in the file; prototype displacement = length_scale x specimen displacement.
building = structures.load_building("five_story")
law = building.isolator.law

# A short calibration of that law on the bundled test (use the full default run for real designs,
# or load a saved one: propagate(".../posterior.nc", ...)).
cal_path = out / "posterior.nc"
if not cal_path.exists():
    cal = calibrate(load_test("protocol1"), law, steps=200, seed=0, progress=False)
    cal.to_netcdf(cal_path)

rs = propagate(
    cal_path,
    building,
    ["elcentro", "sanfernando", "rinaldi", "tabas", "santamonica"],
    n_samples=100,
    scales=(0.5, 1.0, 1.5),  # stripes for the fragility fit
    seed=0,
    store=out / "store",
)

pooled = rs.summary()
print(pooled[pooled["record"] == "all records"].drop(columns="record").to_string(index=False))
print(rs.variance_split()[["demand", "scale", "share_params", "share_records"]].to_string(index=False))
print(rs.exceedance().query("record == 'all records'").to_string(index=False))
for f in rs.fragility():
    print(f"fragility {f.demand} > {f.limit:.3g}: median intensity {f.theta:.3g}, beta {f.beta:.2f} {f.note}")
print(f"runs beyond the calibrated isolator displacement: {100 * rs.extrapolated_share():.1f} %")

rs.table.to_parquet(out / "responses.parquet", index=False)
rs.plot_distributions("iso_disp_peak_m").savefig(out / "iso_disp_per_record.png", dpi=120)
rs.plot_exceedance("drift_ratio_max").savefig(out / "drift_exceedance.png", dpi=120)
rs.plot_fragility().savefig(out / "fragility.png", dpi=120)
print(f"wrote {out}/")
