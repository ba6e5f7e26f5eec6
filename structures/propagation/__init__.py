"""Posterior propagation through ground motions: its inputs, the workflow (1-D and record pairs),
executors (local, Dask), the Parquet store, response sets, summaries, fragility, stripes and design
answers."""
