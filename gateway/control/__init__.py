"""DP controller and thrust allocation: pure numerics (arrays in, arrays out; no I/O, threads or clocks)."""
