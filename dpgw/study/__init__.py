"""``dpgw study``: Monte Carlo studies of the observers over scenarios × sea states × seeds, on Dask.

spec (the grid, from flags or a TOML file) → case (one simulation, every observer on its measurements,
scored: scores) → runner (serial or Dask, the per-case cache: cache) → outputs (table, summary, plots).
docs/study.md describes the study, each column and how to run it on a cluster.
"""
