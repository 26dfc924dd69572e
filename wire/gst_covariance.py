"""A GNSS fix's position covariance from NMEA GST: the error ellipse in full, not only its per-axis σ.

GST gives, 1σ in metres: the semi-major and semi-minor axes of the horizontal error ellipse (a, b), the
orientation θ of the semi-major axis, and the standard deviations of latitude, longitude and altitude
(σ_N, σ_E, σ_U). The ellipse is the horizontal covariance's eigen-decomposition (docs/nmea.md).

**Convention.** θ is a bearing, like every NMEA angle: from true north, clockwise (toward east), so the
major axis points along u = (cos θ, sin θ) in (north, east) and the minor axis along v = (−sin θ, cos θ).
With R(θ) = [[cos θ, −sin θ], [sin θ, cos θ]] in (N, E)::

    C_NE = R(θ) diag(a², b²) R(θ)ᵀ = a² u uᵀ + b² v vᵀ
    C_NN = a² cos²θ + b² sin²θ,  C_EE = a² sin²θ + b² cos²θ,  C_NE = (a² − b²) sin θ cos θ.

An axis has no direction: θ and θ + 180° give the same matrix, and a = b is a circle whatever θ. The
marginals C_NN and C_EE are σ_N² and σ_E², so a receiver that fills both parts of GST gives the same
figures twice: checked on a Septentrio PolaRx2 log (a = 317.719, b = 3.872, θ = 1.791°: √C_NN = 317.564,
√C_EE = 10.657, the sentence's σ_lat 317.563 and σ_lon 10.659, within what printing θ to 0.001° moves).
The marginals fix which axis θ is measured from (from east, σ_N and σ_E would swap) but not its sense,
which the sentence's definition gives (clockwise, as a bearing).

**Which fields win.** The ellipse when it is complete (a, b and θ, or a = b without θ), because it alone
has the correlation; its marginals must then agree with σ_N and σ_E when the receiver gives those too,
within `AGREE_REL` (or `AGREE_ABS_M`, the print resolution of a receiver with one decimal). When they
disagree the receiver has filled the ellipse with something else (another confidence level, the range
residuals' ellipse, a stale value): the per-axis σ_N, σ_E win — they are the fix's per-axis precision
itself, what a ROS driver such as nmea_navsat_driver puts on a NavSatFix, and what dpgw used before —
and the covariance is diagonal, reported as `INCONSISTENT`. Without a complete ellipse: σ_N, σ_E on the
diagonal. Without either: no covariance. The up variance is σ_U², uncorrelated with the horizontal (GST
gives no more). Without σ_U it is not known, and 0 there would read as an exact height: it is then
approximated as (`UP_PER_HORIZONTAL` σ_H)², σ_H = √((C_NN + C_EE)/2), the way ROS's nmea_navsat_driver
approximates a fix's vertical error (twice its horizontal one: satellites are all above the antenna, so
VDOP is typically 1.5-2 × HDOP), and `up_known` is False: the published covariance type is then
APPROXIMATED (ROS NavSatFix, Foxglove LocationFix), not KNOWN or DIAGONAL_KNOWN.

**Zeros.** A receiver prints 0 for a σ below its print resolution (an RTK fix's 0.02 m as "0.0"),
and some fill fields they do not compute with zeros. Neither is an exact position, and a zero
covariance would be published as KNOWN and drawn as an exact fix: a sentence whose horizontal figures
are all 0 gives no covariance, and a σ_U of 0 counts as no σ_U (the up variance is then approximated,
as above). One zero axis beside a non-zero one is kept (an ellipse thinner than the print resolution;
`unit_shape`'s floor keeps its shape finite).

Negative σ and a non-finite orientation never get here: the decoder rejects such a sentence as a
``bad_field`` (`wire.codecs.nmea`). A σ above `SIGMA_MAX_M`, finite but so large that its square, the
sums and doublings made of squares here, or a product of two variances downstream (an ellipse's
determinant) would overflow to infinity, counts as absent: an infinite
covariance is no figure (JSON has no infinity, so the LocationFix would carry `null` where Foxglove's
schema has a number, and the ellipse shape of `unit_shape` would be NaN), and the rules above then use
what else the sentence gives.
"""

from __future__ import annotations

import math
from typing import Final, NamedTuple

from wire.codecs.nmea import Gst

AGREE_REL: Final = 0.1
"""The ellipse's marginal σ and the sentence's σ_lat / σ_lon agree within 10 % ..."""
AGREE_ABS_M: Final = 0.1
"""... or within 0.1 m (a receiver printing one decimal rounds each of the four figures by 0.05 m)."""
SIGMA_MAX_M: Final = 1e75
"""Largest σ taken (m): its square is ≤ 1e150, so every sum of squares here (and the approximated up
variance, 4 × their mean) stays finite, and so does a product of two variances downstream: the
determinant C_NN·C_EE − C_NE² of `gateway.references.monitor.ellipse_reach` (with σ up to 1e150 it was
inf − inf, the re-acquisition gate NaN, and every fix back after an outage outside it). A real receiver's
σ is below the Earth's radius; larger is a sentence that means nothing."""

ELLIPSE, AXES, INCONSISTENT = "ellipse", "axes", "inconsistent"
"""Where a `GstCovariance` came from: the full ellipse; σ_lat / σ_lon alone (no complete ellipse); σ_lat /
σ_lon because the ellipse disagrees with them."""


UP_PER_HORIZONTAL: Final = 2.0
"""Without GST's σ_alt, the up 1σ taken as this many times the horizontal (RMS) 1σ (nmea_navsat_driver's
ratio: its altitude σ is 2 × HDOP × ε where its horizontal σ is HDOP × ε)."""


class GstCovariance(NamedTuple):
    """A fix's position covariance (m²): the horizontal in north/east and the up variance (``up_known``
    False: σ_alt was empty and ``uu`` is approximated from the horizontal)."""

    nn: float
    ne: float
    ee: float
    uu: float
    origin: str  # ELLIPSE, AXES or INCONSISTENT
    up_known: bool = True

    @property
    def full(self) -> bool:
        """Whether the off-diagonal is known (from the ellipse), not merely zero by assumption."""
        return self.origin == ELLIPSE

    def enu(self) -> list[float]:
        """The 3×3 covariance in east, north, up, row-major (NavSatFix's and Foxglove's order): the
        horizontal block is the north/east one with both indices swapped, so the off-diagonal stays
        C_NE (cov(E, N) = cov(N, E))."""
        return [self.ee, self.ne, 0.0, self.ne, self.nn, 0.0, 0.0, 0.0, self.uu]

    def sigma_m(self) -> float:
        """One horizontal 1σ: √((C_NN + C_EE) / 2), the RMS of the two marginals (the trace, so the same
        whatever the axes)."""
        return math.sqrt((self.nn + self.ee) / 2.0)


def ellipse_covariance_ne(
    sigma_major_m: float, sigma_minor_m: float, orient_rad: float
) -> tuple[float, float, float]:
    """(C_NN, C_NE, C_EE) of the error ellipse: R(θ) diag(a², b²) R(θ)ᵀ, θ clockwise from north."""
    a2, b2 = sigma_major_m * sigma_major_m, sigma_minor_m * sigma_minor_m
    c, s = math.cos(orient_rad), math.sin(orient_rad)
    return a2 * c * c + b2 * s * s, (a2 - b2) * s * c, a2 * s * s + b2 * c * c


def _agree(marginal_var: float, sigma: float) -> bool:
    m = math.sqrt(marginal_var)
    return abs(m - sigma) <= max(AGREE_REL * sigma, AGREE_ABS_M)


def gst_covariance(g: Gst) -> GstCovariance | None:
    """The position covariance a GST gives (the rules in the module docstring), or None without one."""
    a, b, theta = _sigma(g.sigma_major_m), _sigma(g.sigma_minor_m), g.orient_rad
    lat, lon, alt = _sigma(g.sigma_lat_m), _sigma(g.sigma_lon_m), _sigma(g.sigma_alt_m)
    if alt == 0.0:
        alt = None  # (an exact height is no figure: approximated from the horizontal)
    if a is not None and b is not None and (theta is not None or a == b) and a + b > 0.0:
        nn, ne, ee = ellipse_covariance_ne(a, b, theta or 0.0)
        if lat is None or lon is None or (_agree(nn, lat) and _agree(ee, lon)):
            return _with_up(nn, ne, ee, alt, ELLIPSE)
        return _with_up(lat * lat, 0.0, lon * lon, alt, INCONSISTENT)
    if lat is None or lon is None:
        return None
    return _with_up(lat * lat, 0.0, lon * lon, alt, AXES)


def _sigma(sigma_m: float | None) -> float | None:
    """A GST σ as the rules take it: None when absent or above `SIGMA_MAX_M`."""
    return sigma_m if sigma_m is not None and sigma_m <= SIGMA_MAX_M else None


def _with_up(nn: float, ne: float, ee: float, sigma_alt_m: float | None, origin: str) -> GstCovariance | None:
    """The covariance with its up variance: σ_alt², or without σ_alt (UP_PER_HORIZONTAL σ_H)², not known;
    None when the horizontal part is all zero (the module docstring's zeros)."""
    if not nn + ee > 0.0:
        return None  # every horizontal figure 0: below the print resolution, or not computed
    if sigma_alt_m is not None:
        return GstCovariance(nn, ne, ee, sigma_alt_m * sigma_alt_m, origin)
    return GstCovariance(nn, ne, ee, UP_PER_HORIZONTAL * UP_PER_HORIZONTAL * (nn + ee) / 2.0, origin, False)


SHAPE_FLOOR: Final = 0.01
"""Added to both axes of an ellipse's unit shape (`unit_shape`): no shape thinner than about 14:1 in σ."""


def unit_shape(cov_ne: tuple[float, float, float]) -> tuple[float, float, float] | None:
    """The shape of a horizontal covariance without its size: (Ĉ + f I) / (1 + f) with Ĉ = C / (tr C / 2)
    (unit RMS σ, the trace of I) and f = `SHAPE_FLOOR`, so that a line or a needle-thin ellipse does not
    make one axis count infinitely; I for a circle; None for a zero covariance (no shape). What lets a
    receiver's ellipse say in which direction its fixes are good while dpgw's measured spread of the same
    fixes says how good (the pooling weights, the prediction test: docs/integrity.md)."""
    nn, ne, ee = cov_ne
    # Scaled to its largest element first: the shape does not depend on the size, and a covariance of
    # subnormal size (a receiver's 1e-159 m axis squared) would otherwise give 1 / half-trace = inf and
    # NaN shapes. Not finite: no shape either.
    biggest = max(abs(nn), abs(ne), abs(ee))
    if not (0.0 < biggest < math.inf):
        return None
    nn, ne, ee = nn / biggest, ne / biggest, ee / biggest
    # A covariance is positive semi-definite: ne² <= nn·ee. One made from axes near the smallest floats
    # loses that to rounding (a 4e-162 m axis squared is a subnormal of a few bits, and its products with
    # cos and sin round each on their own: ne² came out 1.3 nn·ee). Held to the bound, the shape below stays
    # positive definite, as the prediction test's reach needs; a covariance that keeps the bound is
    # untouched.
    if nn >= 0.0 and ee >= 0.0:
        bound = math.sqrt(nn * ee)
        if abs(ne) > bound:
            ne = math.copysign(bound, ne)
    half_trace = (nn + ee) / 2.0
    if not half_trace > 0.0:
        return None
    k = 1.0 / (half_trace * (1.0 + SHAPE_FLOOR))
    return (nn + SHAPE_FLOOR * half_trace) * k, ne * k, (ee + SHAPE_FLOOR * half_trace) * k
