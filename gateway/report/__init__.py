"""The replay report: metrics and PNG plots in the style of the papers' figures.

After a sea trial the estimators are re-run on the recorded data (`dpgw replay`); this package turns the
result into what the papers show (Fossen & Strand 1999, Figs. 9-14; Torsetnes et al. 2004, Figs. 3-8):
measurement against the LF and WF estimates per DOF, velocities, bias, the wave frequency in use, and the
power spectra that show the wave filter at work. `docs/report.md` gives every formula and choice.

One job per module: `data` (the inputs, checked and sorted), `spectra` (resampling, Welch PSD, spectral
peak), `metrics` (`compute_metrics`: pure numerics, arrays in, a JSON-able dict out), `findings` (what
the console must say too: an observer that amplifies), `plots` (matplotlib,
imported only when drawing), `markdown` (report.md) and `writer` (`write_report`, the only one that writes
files). matplotlib is imported only to draw: an install without it still gets the metrics and the
table.
"""

from gateway.report.data import ObserverTrace, ReplayData
from gateway.report.metrics import compute_metrics, wave_band_for_length
from gateway.report.plots import decimate
from gateway.report.writer import write_report

__all__ = [
    "ObserverTrace",
    "ReplayData",
    "compute_metrics",
    "decimate",
    "wave_band_for_length",
    "write_report",
]
