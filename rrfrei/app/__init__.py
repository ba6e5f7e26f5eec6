"""The application layer: the ``rrfrei`` command, its commands, the demo and its HTML page.

Layers of the project, bottom to top (imports point down only; ``tests/test_layers.py`` imports
each layer in a fresh interpreter and checks that nothing above it was loaded):

0. ``rrfrei._jit_cache`` (and the ``rrfrei`` package root, which only sets it up): the Numba
   cache locator (a private per-user folder keyed on the kernel sources), imported first by
   every package.
1. ``ground_motions``: records, spectra, scaling.
2. ``rrfrei`` core: ``laws``, ``simulate``, ``io``, ``energy``, ``protocols``, ``calibration``,
   ``gap`` (the gap engine), ``budget``, ``errors``, ``_inputs``.
3. ``structures`` (buildings, time histories, propagation; uses ground motions and the core) and,
   beside it, ``rubber`` (the PRF model and its gap diagnosis on the core's gap engine); neither
   imports the other.
4. ``rrfrei.app`` (this package): :mod:`rrfrei.app.cli` and :mod:`rrfrei.app.commands` (argument
   parsing, tables, JSON, figures; no numerics), :mod:`rrfrei.app.demo` (every workflow on the
   bundled data) and :mod:`rrfrei.app.report` (the self-contained HTML page).

Run it as ``rrfrei ...`` (the console script) or ``python -m rrfrei.app ...``.
"""
