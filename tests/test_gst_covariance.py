"""GST's error ellipse as a covariance: the conversion's properties, a real receiver's sentences, the
fallbacks, the ellipse's reach used by the re-acquisition gate, and what the pipeline does with it."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from gateway.fusion import Fusion
from gateway.pipeline import RawEvent
from gateway.references import ReferenceMonitor
from gateway.references.monitor import ELLIPSE_EPS_M2, Prediction, ellipse_reach
from observers.vessel import load_vessel
from tests.test_nmea_decode import GPSD, log_bytes, need
from tests.test_pipeline import T0, S, gga_at, nmea_src, pipeline
from wire.codecs import nmea_encode as enc
from wire.codecs.nmea import Gst, decode
from wire.foxglove import COVARIANCE_APPROXIMATED, COVARIANCE_KNOWN, location_fix
from wire.gst_covariance import (
    AXES,
    ELLIPSE,
    INCONSISTENT,
    SHAPE_FLOOR,
    UP_PER_HORIZONTAL,
    ellipse_covariance_ne,
    gst_covariance,
    unit_shape,
)

sigmas = st.floats(0.0, 1e3, allow_subnormal=False)
angles = st.floats(-4 * math.pi, 4 * math.pi)


def reference(a: float, b: float, theta: float) -> np.ndarray:
    """R(θ) diag(a², b²) R(θ)ᵀ by matrices, in (north, east), R turning north toward east."""
    c, s = math.cos(theta), math.sin(theta)
    r = np.array([[c, -s], [s, c]])
    return r @ np.diag([a * a, b * b]) @ r.T


def as_matrix(nn: float, ne: float, ee: float) -> np.ndarray:
    return np.array([[nn, ne], [ne, ee]])


@given(sigmas, sigmas, angles)
def test_the_ellipse_is_a_covariance_with_its_axes_as_eigenpairs(a: float, b: float, theta: float) -> None:
    c = as_matrix(*ellipse_covariance_ne(a, b, theta))
    scale = max(a, b, 1e-9) ** 2
    np.testing.assert_allclose(c, reference(a, b, theta), atol=1e-12 * scale)
    eig = np.linalg.eigvalsh(c)
    assert eig[0] >= -1e-12 * scale  # positive semidefinite
    np.testing.assert_allclose(sorted(eig), sorted((a * a, b * b)), atol=1e-9 * scale)
    # the major axis lies along the bearing θ: u = (cos θ, sin θ) in (N, E) is an eigenvector for a²
    u = np.array([math.cos(theta), math.sin(theta)])
    np.testing.assert_allclose(c @ u, a * a * u, atol=1e-9 * scale)
    # marginals
    assert c[0, 0] == pytest.approx(
        a * a * math.cos(theta) ** 2 + b * b * math.sin(theta) ** 2, abs=1e-9 * scale
    )
    assert c[1, 1] == pytest.approx(
        a * a * math.sin(theta) ** 2 + b * b * math.cos(theta) ** 2, abs=1e-9 * scale
    )


@given(sigmas, sigmas, angles)
def test_an_axis_turned_by_180_degrees_is_the_same_ellipse(a: float, b: float, theta: float) -> None:
    scale = max(a, b, 1e-9) ** 2
    np.testing.assert_allclose(
        ellipse_covariance_ne(a, b, theta + math.pi), ellipse_covariance_ne(a, b, theta), atol=1e-12 * scale
    )
    # and swapping the axes is turning by 90°
    np.testing.assert_allclose(
        ellipse_covariance_ne(b, a, theta + math.pi / 2),
        ellipse_covariance_ne(a, b, theta),
        atol=1e-9 * scale,
    )


@given(sigmas, angles)
def test_equal_axes_are_a_circle_whatever_the_orientation(a: float, theta: float) -> None:
    nn, ne, ee = ellipse_covariance_ne(a, a, theta)
    assert nn == pytest.approx(a * a, rel=1e-12, abs=1e-300) and ee == pytest.approx(
        a * a, rel=1e-12, abs=1e-300
    )
    assert abs(ne) <= 1e-12 * a * a


def test_a_real_receivers_ellipse_gives_its_own_latitude_and_longitude_sigmas() -> None:
    """Septentrio PolaRx2 (gpsd's log): an ellipse 80 times longer than wide, 1.8° off north. Its
    marginals are the sentence's σ lat / σ lon to the print resolution (3 decimals of m and °), which
    fixes θ as measured from north: from east they would be swapped (σ_N ≈ 10.7 m, σ_E ≈ 317.6 m)."""
    data = log_bytes(need(GPSD / "polarx2.log"))
    gsts = [s for line in data.decode().splitlines() if "GST" in line and isinstance(s := decode(line), Gst)]
    assert len(gsts) == 5
    for g in gsts:
        assert g.orient_rad is not None and g.sigma_lat_m is not None and g.sigma_lon_m is not None
        cov = gst_covariance(g)
        assert cov is not None and cov.origin == ELLIPSE and cov.full
        # each figure printed to ±0.0005 (m or °): θ's rounding moves the east marginal by up to a·δθ
        tol = 1.5e-3 + g.sigma_major_m * math.radians(0.0005)  # type: ignore[operator]
        assert math.sqrt(cov.nn) == pytest.approx(g.sigma_lat_m, abs=tol)
        assert math.sqrt(cov.ee) == pytest.approx(g.sigma_lon_m, abs=tol)
        assert cov.uu == pytest.approx(g.sigma_alt_m**2)  # type: ignore[operator]
        # the major axis a few degrees east of north: north and east errors positively correlated
        assert 0 < cov.ne < math.sqrt(cov.nn * cov.ee)
        # measured from east instead, the marginals would be far off
        nn_e, _, ee_e = ellipse_covariance_ne(g.sigma_major_m, g.sigma_minor_m, math.pi / 2 - g.orient_rad)  # type: ignore[arg-type]
        assert abs(math.sqrt(nn_e) - g.sigma_lat_m) > 100.0 and abs(math.sqrt(ee_e) - g.sigma_lon_m) > 100.0
    first = gst_covariance(gsts[0])
    assert first is not None
    expected = ellipse_covariance_ne(317.719, 3.872, math.radians(1.791))
    assert (first.nn, first.ne, first.ee) == pytest.approx(expected)
    # in ENU, row-major: [E E, E N, 0; N E, N N, 0; 0, 0, U U]
    assert first.enu() == pytest.approx(
        [expected[2], expected[1], 0, expected[1], expected[0], 0, 0, 0, 180.746**2]
    )


def _gst(**kw: float | None) -> Gst:
    fields: dict[str, float | None] = {
        "sigma_major_m": None, "sigma_minor_m": None, "orient_rad": None,
        "sigma_lat_m": None, "sigma_lon_m": None, "sigma_alt_m": None,
    }  # fmt: skip
    fields.update(kw)
    return Gst("GP", 0.0, 0.5, **fields)  # type: ignore[arg-type]


def test_missing_fields_fall_back_to_what_is_given_and_a_disagreeing_ellipse_loses() -> None:
    # no ellipse: σ lat / lon on the diagonal (what dpgw did before)
    cov = gst_covariance(_gst(sigma_lat_m=0.3, sigma_lon_m=0.4, sigma_alt_m=1.0))
    assert (
        cov is not None
        and cov[:4] == pytest.approx((0.09, 0.0, 0.16, 1.0))
        and cov.origin == AXES
        and not cov.full
    )
    # an ellipse without its orientation: the same
    cov = gst_covariance(_gst(sigma_major_m=0.5, sigma_minor_m=0.2, sigma_lat_m=0.3, sigma_lon_m=0.4))
    assert cov is not None and cov.origin == AXES and not cov.up_known  # (no σ alt: approximated)
    # a circle needs no orientation
    cov = gst_covariance(_gst(sigma_major_m=0.5, sigma_minor_m=0.5))
    assert cov is not None and cov[:4] == pytest.approx((0.25, 0.0, 0.25, 1.0)) and cov.origin == ELLIPSE
    # the ellipse alone
    cov = gst_covariance(_gst(sigma_major_m=0.5, sigma_minor_m=0.2, orient_rad=math.radians(30)))
    assert (
        cov is not None
        and cov.origin == ELLIPSE
        and cov.ne == pytest.approx(0.21 * math.sin(math.radians(60)) / 2)
    )
    # an ellipse whose marginals are not the sentence's σ: σ lat / lon win
    cov = gst_covariance(
        _gst(sigma_major_m=5.0, sigma_minor_m=0.2, orient_rad=0.0, sigma_lat_m=0.3, sigma_lon_m=0.4)
    )
    assert cov is not None and cov[:3] == pytest.approx((0.09, 0.0, 0.16)) and cov.origin == INCONSISTENT
    # nothing horizontal
    assert gst_covariance(_gst(sigma_alt_m=1.0)) is None
    assert gst_covariance(_gst(sigma_lat_m=0.3)) is None


@given(st.floats(0.05, 50.0), st.floats(0.0, 1.0), st.floats(0.0, math.pi))
def test_an_encoded_gst_decodes_to_its_ellipse(a: float, ratio: float, theta: float) -> None:
    """A receiver's sentence (3 decimals, orientation to 0.1°) with σ lat / lon its ellipse's marginals:
    the ellipse is used, and its covariance is the one encoded, to the print resolution."""
    b = a * ratio
    nn, ne, ee = ellipse_covariance_ne(a, b, theta)
    text = enc.gst(
        "GP", datetime(2026, 6, 1, tzinfo=UTC), rms_m=0.5, sigma_major_m=a, sigma_minor_m=b,
        orient_rad=theta, sigma_lat_m=math.sqrt(nn), sigma_lon_m=math.sqrt(ee), sigma_alt_m=1.0,
    )  # fmt: skip
    g = decode(text.strip())
    assert isinstance(g, Gst)
    cov = gst_covariance(g)
    assert cov is not None and cov.origin == ELLIPSE
    # printed a, b to ±0.5 mm, θ to ±0.05°: the covariance within what that moves it
    tol = 2 * a * 1e-3 + a * a * math.radians(0.05) * 1.01 + 1e-9
    assert (cov.nn, cov.ne, cov.ee) == pytest.approx((nn, ne, ee), abs=tol)


@given(st.floats(0.01, 100.0), st.floats(0.01, 1.0), angles, angles, st.floats(0.01, 1e3))
def test_the_ellipse_reach_is_the_mahalanobis_boundary(
    a: float, ratio: float, theta: float, direction: float, length: float
) -> None:
    """‖d‖ ≤ k·reach(d) ⟺ dᵀ C⁻¹ d ≤ k²; along the major axis the reach is a, across it b."""
    b = a * ratio
    cov = ellipse_covariance_ne(a, b, theta)
    eps = ELLIPSE_EPS_M2  # (the regularisation: 1 µm² on each variance)
    assert ellipse_reach(cov, math.cos(theta), math.sin(theta)) == pytest.approx(
        math.sqrt(a * a + eps), rel=1e-6
    )
    assert ellipse_reach(cov, -math.sin(theta), math.cos(theta)) == pytest.approx(
        math.sqrt(b * b + eps), rel=1e-6
    )
    d = np.array([math.cos(direction), math.sin(direction)]) * length
    reach = ellipse_reach(cov, *d)
    m2 = float(d @ np.linalg.solve(reference(a, b, theta) + eps * np.eye(2), d))
    assert (length / reach) ** 2 == pytest.approx(m2, rel=1e-6)


def test_ellipse_reach_of_a_line_and_of_nothing() -> None:
    line = ellipse_covariance_ne(2.0, 0.0, 0.0)  # all north
    assert ellipse_reach(line, 1.0, 0.0) == pytest.approx(2.0)
    assert ellipse_reach(line, 0.0, 1.0) < 1e-5
    assert ellipse_reach((0.0, 0.0, 0.0), 1.0, 1.0) < 1e-5
    assert ellipse_reach(line, 0.0, 0.0) == 0.0


# ---------------------------------------------------------------------------------------------- pipeline


def _gst_bytes(a: float, b: float, theta_deg: float, lat: float | None, lon: float | None) -> bytes:
    return enc.gst(
        "GP", datetime(2026, 6, 1, tzinfo=UTC), rms_m=0.5, sigma_major_m=a, sigma_minor_m=b,
        orient_rad=math.radians(theta_deg), sigma_lat_m=lat, sigma_lon_m=lon, sigma_alt_m=1.0,
    ).encode()  # fmt: skip


def test_the_pipeline_publishes_the_ellipse_and_counts_one_that_disagrees() -> None:
    p = pipeline([nmea_src("gps", ["position", "heading"], timeout_s=2.0)])
    hdt = enc.hdt("HE", 0.3).encode()
    p.feed(RawEvent(T0, "gps", gga_at(0.0, 0.0) + hdt))
    # a = 0.5, b = 0.2 at 30° east of north: σ_N = 0.444, σ_E = 0.304, C_NE = 0.0909
    p.feed(RawEvent(T0 + S // 10, "gps", _gst_bytes(0.5, 0.2, 30.0, 0.444, 0.304)))
    out = p.feed(RawEvent(T0 + S, "gps", gga_at(0.0, 0.0) + hdt))
    (fix,) = [o.payload for o in out if o.topic == "/gnss/gps/fix"]
    nn, ne, ee = ellipse_covariance_ne(0.5, 0.2, math.radians(30.0))
    assert fix["position_covariance_type"] == 3  # KNOWN
    assert fix["position_covariance"] == pytest.approx([ee, ne, 0, ne, nn, 0, 0, 0, 1.0])
    assert ne == pytest.approx(0.0909, abs=1e-4)
    (m,) = [o.payload for o in out if o.topic == "/dp/measurement"]
    assert m["sigma_m"] == pytest.approx(math.sqrt((nn + ee) / 2))
    assert m["covariance_ne_m2"] == pytest.approx([nn, ne, ee])
    assert p.fusion.position_covariance_ne(T0 + S) == pytest.approx((nn, ne, ee))
    assert not p.counters["gps"].rejected
    # an ellipse that is not its own σ lat / lon: the per-axis σ, diagonal, and counted
    p.feed(RawEvent(T0 + 2 * S, "gps", _gst_bytes(3.0, 0.2, 30.0, 0.444, 0.304)))
    out = p.feed(RawEvent(T0 + 3 * S, "gps", gga_at(0.0, 0.0) + hdt))
    (fix,) = [o.payload for o in out if o.topic == "/gnss/gps/fix"]
    assert fix["position_covariance_type"] == 2
    assert fix["position_covariance"] == pytest.approx([0.304**2, 0, 0, 0, 0.444**2, 0, 0, 0, 1.0])
    assert p.counters["gps"].rejected == {}  # used: a caveat, not a reject
    assert p.counters["gps"].warnings == {"gst_ellipse_inconsistent": 1}
    # a negative σ or an orientation that is no number: a rejected sentence, the last good one stands
    bad = [b"$GPGST,120000.00,0.5,-1,0.2,30,0.4,0.3,1.0", b"$GPGST,120000.00,0.5,0.5,0.2,nan,0.4,0.3,1.0"]
    for body in bad:
        text = body.decode()[1:]
        p.feed(RawEvent(T0 + 3 * S + 1, "gps", f"${text}*{enc.checksum(text)}\r\n".encode()))
    assert p.counters["gps"].rejected["bad_field"] == 2
    assert p.fusion.position_covariance_ne(T0 + 3 * S + 2) == pytest.approx((0.444**2, 0.0, 0.304**2))


def test_the_reacquisition_gate_is_wider_along_the_receivers_wide_axis() -> None:
    """The gate after an outage: the fixed gate plus the reach of the 3σ ellipse toward the fix. An
    ellipse 3 m by 0.1 m pointing north-east: a fix 10 m off toward north-east is inside (5 + 9 m), the
    same distance toward north-west is outside (5 + 0.3 m); a circle of the same RMS σ lets both in."""
    p = pipeline([nmea_src("gps", ["position", "heading"])])
    m = p.monitor
    gate = m._limits["position"].gate  # the configured prediction_gate_m
    assert gate == pytest.approx(5.0)
    cov = ellipse_covariance_ne(3.0, 0.1, math.radians(45.0))
    r = 10.0 / math.sqrt(2)
    assert m.beyond_prediction_gate("position", (r, r), (0.0, 0.0), cov_ne=cov) == ""
    off = m.beyond_prediction_gate("position", (r, -r), (0.0, 0.0), cov_ne=cov)
    assert off.startswith("10 m from the dead-reckoned estimate") and "gate 5.3 m" in off
    sigma = math.sqrt((cov[0] + cov[2]) / 2)
    circle = (sigma**2, 0.0, sigma**2)
    assert m.beyond_prediction_gate("position", (r, -r), (0.0, 0.0), cov_ne=circle) == ""
    assert m.beyond_prediction_gate("position", (r, -r), (0.0, 0.0)) != ""  # no covariance: the fixed gate


@given(
    st.floats(-3.0, 308.0),  # σ's decimal exponent: every size a float holds, not mostly the largest
    st.floats(0.0, 1.0),
    st.floats(math.radians(1.0), math.radians(89.0)),
    angles,
)
def test_any_gst_ellipse_taken_gives_the_reacquisition_gate_a_size(
    exponent: float, ratio: float, theta: float, direction: float
) -> None:
    """A GST ellipse up to the float's limit: whatever covariance `gst_covariance` takes from it, the
    gate after an outage has a size, never NaN. Above σ ≈ 1e77 m the determinant the reach is made of
    (C_NN·C_EE − C_NE²) overflows to inf − inf: the gate was NaN, and every fix returning after an outage
    was called outside it ("gate nan m") and restarted the observers."""
    a = 10.0**exponent
    cov = gst_covariance(_gst(sigma_major_m=a, sigma_minor_m=a * ratio, orient_rad=theta))
    if cov is None:
        return
    assert not math.isnan(ellipse_reach(cov[:3], math.cos(direction), math.sin(direction)))
    p = pipeline([nmea_src("gps", ["position", "heading"])])
    off = p.monitor.beyond_prediction_gate("position", (100.0, 100.0), (0.0, 0.0), cov_ne=cov[:3])
    assert "nan" not in off


# ---------------------------------------------------------------------------------------------- pooling


def _pooled(fusion: Fusion, now: int) -> tuple[float, float]:
    y, valid = fusion.measurement(now)
    assert valid[0] and valid[1]
    return float(y[0]), float(y[1])


def test_pooling_takes_each_receivers_good_axis_from_its_ellipse() -> None:
    """Two receivers, equally weighted by their measured spread: A long north-south at (0, 0), B long
    east-west at (2, 2). Pooled with their ellipses as the shape of their weights, the position takes its
    north from B and its east from A (the information-weighted mean, checked against matrices); without
    GST it is the plain mean (1, 1), as it was."""
    vessel = load_vessel("mss_supply")
    f = Fusion(vessel)
    valid = 10 * S
    f.use_position(T0, 0.0, 0.0, "a", 1, valid, weight=4.0)
    f.use_position(T0, 2.0, 2.0, "b", 2, valid, weight=4.0)
    assert _pooled(f, T0 + 1) == (1.0, 1.0)
    ca = ellipse_covariance_ne(3.0, 0.3, 0.0)
    cb = ellipse_covariance_ne(3.0, 0.3, math.pi / 2)
    f.add_position_covariance(T0, ca, "a", valid)
    f.add_position_covariance(T0, cb, "b", valid)
    f.use_position(T0 + 2, 2.0, 2.0, "b", 2, valid, weight=4.0)  # (a change: pooled again)
    n, e = _pooled(f, T0 + 2)
    assert n > 1.9 and e < 0.1

    def info(c: tuple[float, float, float]) -> np.ndarray:
        m = as_matrix(*c) / ((c[0] + c[2]) / 2)
        return 4.0 * np.linalg.inv((m + SHAPE_FLOOR * np.eye(2)) / (1 + SHAPE_FLOOR))

    wa, wb = info(ca), info(cb)
    expected = np.linalg.solve(wa + wb, wb @ np.array([2.0, 2.0]))
    assert (n, e) == pytest.approx(tuple(expected), abs=1e-12)
    # a circle shapes nothing: the scalar mean again; a stale covariance is not used
    f.add_position_covariance(T0, (0.25, 0.0, 0.25), "a", valid)
    f.add_position_covariance(T0, (0.25, 0.0, 0.25), "b", valid)
    f.use_position(T0 + 3, 2.0, 2.0, "b", 2, valid, weight=4.0)
    assert _pooled(f, T0 + 3) == pytest.approx((1.0, 1.0), abs=1e-12)
    f.add_position_covariance(T0, ca, "a", S)
    f.add_position_covariance(T0, cb, "b", S)
    f.use_position(T0 + 2 * S, 2.0, 2.0, "b", 2, valid, weight=4.0)
    assert _pooled(f, T0 + 2 * S) == (1.0, 1.0)


@given(
    st.lists(
        st.tuples(
            st.floats(-50, 50), st.floats(-50, 50), st.floats(0.01, 100.0),
            st.one_of(st.none(), st.tuples(st.floats(0.0, 10.0), st.floats(0.0, 10.0), angles)),
        ),
        min_size=2, max_size=4,
    )
)  # fmt: skip
# a needle along east whose C_NN·C_EE underflows to 0 while C_NE² does not quite (was taken for no covariance)
@example([(0.0, 0.0, 1.0, (0.0, 3.0, 2.6583422225313074e-163)), (0.0, 1.0, 1.0, None)])
# a needle along east whose C_EE is subnormal: 1 / half-trace overflowed to inf and the shape was NaN
@example([(0.0, 0.0, 1.0, None), (0.0, 0.0, 1.0, (0.0, 2.729463112166408e-159, 0.0))])
# and one whose C_EE has few significant bits (1.5e-322): the reference itself rounded when halving it
@example([(0.0, 0.0, 1.0, None), (0.0, 1.0, 1.0, (0.0, 1.2311565815124523e-161, 0.0))])
def test_the_shaped_pooled_position_is_the_information_weighted_mean(
    fixes: list[tuple[float, float, float, tuple[float, float, float] | None]],
) -> None:
    """Whatever the ellipses (lines, zeros, circles, none): the pooled position is (Σ Wᵢ)⁻¹ Σ Wᵢ xᵢ of
    the matrices (a numpy reference beside the scalar kernel), and fixes that agree pool to that point."""
    vessel = load_vessel("mss_supply")
    f, same = Fusion(vessel), Fusion(vessel)
    total, moment = np.zeros((2, 2)), np.zeros(2)
    for i, (n, e, w, ell) in enumerate(fixes):
        shape = np.eye(2)
        if ell is not None:
            c = ellipse_covariance_ne(*ell)
            f.add_position_covariance(T0, c, str(i), 10 * S)
            same.add_position_covariance(T0, c, str(i), 10 * S)
            if c[0] + c[2] > 0:
                # (scaled to its largest element first: halving a subnormal trace rounds)
                unit = as_matrix(*c) / max(map(abs, c))
                shape = (unit / (np.trace(unit) / 2) + SHAPE_FLOOR * np.eye(2)) / (1 + SHAPE_FLOOR)
        f.use_position(T0, n, e, str(i), i, 10 * S, weight=w)
        same.use_position(T0, 3.0, -4.0, str(i), i, 10 * S, weight=w)
        wi = w * np.linalg.inv(shape)
        total += wi
        moment += wi @ np.array([n, e])
    expected = np.linalg.solve(total, moment)
    assert _pooled(f, T0) == pytest.approx(tuple(expected), abs=1e-9 * (1 + np.abs(expected).max()))
    assert _pooled(same, T0) == pytest.approx((3.0, -4.0), abs=1e-12)


def _monitor_with_spread() -> ReferenceMonitor:
    """A pipeline's reference monitor whose DGPS has scattered 1 m (1σ, measured) for 12 fixes."""
    m = pipeline([nmea_src("gps", ["position", "heading"])]).monitor
    for k in range(12):
        assert m.position("gps", T0 + k * S // 10, 0.0, 2.0 * (k % 2), 1, None)
    assert m.sigma_m("gps") == pytest.approx(1.0)
    return m


@pytest.mark.parametrize(
    ("innovation", "isotropic", "shaped"),
    [((8.6, 0.0), False, True), ((0.0, 6.0), True, False), ((0.0, 4.9), True, True)],
)
def test_the_prediction_test_is_shaped_by_the_receivers_ellipse(
    innovation: tuple[float, float], isotropic: bool, shaped: bool
) -> None:
    """The gate g + 3σ (σ the measured spread, about 1 m: 8 m) becomes g + 3σ·reach of the unit shape of
    a GST ellipse long north-south (3 m by 0.1 m): about 9.2 m to the north, 5.3 m to the east, so a fix
    8.6 m north of the prediction passes and one 6 m east does not; inside the fixed gate both pass."""
    fix = (0.0, 1.0)
    pred = Prediction((fix[0] - innovation[0], fix[1] - innovation[1]), 0.0)
    shape = unit_shape(ellipse_covariance_ne(3.0, 0.1, 0.0))
    assert shape is not None
    assert _monitor_with_spread().position("gps", T0 + 2 * S, *fix, 1, pred) is isotropic
    assert _monitor_with_spread().position("gps", T0 + 2 * S, *fix, 1, pred, shape) is shaped
    # a circle is no shape: the isotropic test to the bit
    circle = unit_shape((0.3, 0.0, 0.3))
    assert circle == pytest.approx((1.0, 0.0, 1.0))
    assert _monitor_with_spread().position("gps", T0 + 2 * S, *fix, 1, pred, circle) is isotropic


@given(
    st.floats(0.0, 1e100, allow_subnormal=True),
    st.floats(0.0, 1e100, allow_subnormal=True),
    angles,
    st.integers(-40, 40),
)
@example(0.0, 2.3020606067225963e-161, 1.0, -1)  # (found by CI: halved, its subnormal elements lost bits)
def test_the_shape_is_finite_and_the_same_whatever_the_size(a: float, b: float, theta: float, k: int) -> None:
    """`unit_shape` of any ellipse, down to subnormal axes: None for a zero one, else finite, of trace 2,
    positive definite, and the same for the ellipse scaled by 2^k (where that is exact in floating point).
    """
    cov = ellipse_covariance_ne(a, b, theta)
    shape = unit_shape(cov)
    if max(map(abs, cov)) == 0.0:
        assert shape is None
        return
    assert shape is not None and all(math.isfinite(x) for x in shape)
    nn, ne, ee = shape
    assert nn + ee == pytest.approx(2.0)
    assert nn > 0 and ee > 0 and nn * ee - ne * ne > 0
    scaled = unit_shape(tuple(math.ldexp(x, k) for x in cov))  # type: ignore[arg-type]
    # (compared where the scaling is exact: a subnormal scaled down loses its low bits, and the covariance
    # of a 0 by 2.3e-161 m ellipse halved is then another covariance, of another shape)
    if scaled is not None and all(math.ldexp(math.ldexp(x, k), -k) == x for x in cov):
        assert scaled == pytest.approx(shape, abs=1e-9)
    assert unit_shape((math.inf, 0.0, 1.0)) is None and unit_shape((math.nan, 0.0, 1.0)) is None


def test_an_ellipse_of_subnormal_size_still_has_a_positive_definite_shape() -> None:
    """Found by the property above: a 0 by 4.3e-162 m ellipse at 1 rad. Its covariance's elements are
    subnormal products that round each on their own, so ne² > nn·ee; held to ne² <= nn·ee, the shape is
    positive definite."""
    cov = ellipse_covariance_ne(0.0, 4.327771137615632e-162, 1.0)
    nn, ne, ee = (math.ldexp(x, 1074) for x in cov)  # (scaled exactly: the squares would underflow)
    assert ne * ne > nn * ee * 1.1  # the rounding this is about
    shape = unit_shape(cov)
    assert shape is not None
    nn, ne, ee = shape
    assert nn > 0 and ee > 0 and nn * ee - ne * ne > 0
    # an ordinary covariance is untouched: the same shape to the bit as before the bound
    c = ellipse_covariance_ne(3.0, 0.1, 0.4)
    h = (c[0] + c[2]) / 2 / max(map(abs, c))
    k = 1.0 / (h * (1.0 + SHAPE_FLOOR))
    b = max(map(abs, c))
    assert unit_shape(c) == ((c[0] / b + SHAPE_FLOOR * h) * k, c[1] / b * k, (c[2] / b + SHAPE_FLOOR * h) * k)


def test_an_empty_altitude_sigma_is_not_published_as_an_exact_height() -> None:
    # GST with the ellipse and σ lat / lon but σ alt empty (receivers that give no vertical error)
    text = "GPGST,120000.00,0.5,0.5,0.2,30.0,0.444,0.304,"
    g = decode(f"${text}*{enc.checksum(text)}")
    assert isinstance(g, Gst) and g.sigma_alt_m is None
    cov = gst_covariance(g)
    assert cov is not None and cov.origin == ELLIPSE and not cov.up_known
    # the up variance: (2 σ_H)², σ_H the horizontal RMS σ (nmea_navsat_driver's vertical / horizontal)
    assert cov.uu == pytest.approx(UP_PER_HORIZONTAL**2 * (cov.nn + cov.ee) / 2) and cov.uu > 0
    # published as APPROXIMATED (1): the horizontal block is the ellipse's, the up variance an estimate
    fix = location_fix(0, "gps", 59.0, 10.0, covariance=cov)
    assert fix.position_covariance_type == COVARIANCE_APPROXIMATED
    assert fix.position_covariance == pytest.approx(
        [cov.ee, cov.ne, 0, cov.ne, cov.nn, 0, 0, 0, 4 * (cov.nn + cov.ee) / 2]
    )
    # the same through the pipeline; with σ alt given the type is KNOWN again
    p = pipeline([nmea_src("gps", ["position", "heading"], timeout_s=2.0)])
    hdt = enc.hdt("HE", 0.3).encode()
    p.feed(RawEvent(T0, "gps", gga_at(0.0, 0.0) + hdt))
    p.feed(RawEvent(T0 + S // 10, "gps", f"${text}*{enc.checksum(text)}\r\n".encode()))
    out = p.feed(RawEvent(T0 + S, "gps", gga_at(0.0, 0.0) + hdt))
    (payload,) = [o.payload for o in out if o.topic == "/gnss/gps/fix"]
    assert payload["position_covariance_type"] == COVARIANCE_APPROXIMATED
    assert payload["position_covariance"][8] == pytest.approx(cov.uu)
    p.feed(RawEvent(T0 + 2 * S, "gps", _gst_bytes(0.5, 0.2, 30.0, 0.444, 0.304)))
    out = p.feed(RawEvent(T0 + 3 * S, "gps", gga_at(0.0, 0.0) + hdt))
    (payload,) = [o.payload for o in out if o.topic == "/gnss/gps/fix"]
    assert payload["position_covariance_type"] == COVARIANCE_KNOWN
    assert payload["position_covariance"][8] == pytest.approx(1.0)


def test_zero_sigmas_are_no_exact_fix() -> None:
    """A receiver prints 0 below its print resolution, or fills fields it does not compute with zeros:
    all-zero horizontal figures give no covariance (never a zero one published as KNOWN), a σ alt of 0
    is no σ alt, and one zero axis beside a non-zero one is a thin ellipse, kept."""
    assert gst_covariance(_gst(sigma_major_m=0.0, sigma_minor_m=0.0, orient_rad=0.0)) is None
    assert gst_covariance(_gst(sigma_lat_m=0.0, sigma_lon_m=0.0, sigma_alt_m=0.0)) is None
    zeros = _gst(
        sigma_major_m=0.0, sigma_minor_m=0.0, orient_rad=0.0,
        sigma_lat_m=0.0, sigma_lon_m=0.0, sigma_alt_m=0.0,
    )  # fmt: skip
    assert gst_covariance(zeros) is None
    # a zero ellipse beside small per-axis σ (within the agreement margin of 0): the σ are the figures
    cov = gst_covariance(
        _gst(sigma_major_m=0.0, sigma_minor_m=0.0, orient_rad=0.0, sigma_lat_m=0.05, sigma_lon_m=0.04)
    )
    assert cov is not None and cov.origin == AXES and cov[:3] == pytest.approx((0.0025, 0.0, 0.0016))
    # σ alt 0: the up variance approximated from the horizontal, not an exact height
    cov = gst_covariance(_gst(sigma_lat_m=0.3, sigma_lon_m=0.4, sigma_alt_m=0.0))
    assert cov is not None and not cov.up_known and cov.uu > 0
    # an ellipse thinner than the print resolution: the line, its shape floored to stay finite
    cov = gst_covariance(_gst(sigma_major_m=0.5, sigma_minor_m=0.0, orient_rad=0.0))
    assert cov is not None and cov.origin == ELLIPSE and cov[:3] == pytest.approx((0.25, 0.0, 0.0))
    shape = unit_shape(cov[:3])
    assert shape is not None and all(math.isfinite(v) for v in shape) and shape[2] > 0
    # through the pipeline: the fix's covariance is not published as known-exact, nor used as such
    p = pipeline([nmea_src("gps", ["position", "heading"], timeout_s=2.0)])
    hdt = enc.hdt("HE", 0.3).encode()
    p.feed(RawEvent(T0, "gps", gga_at(0.0, 0.0) + hdt))
    text = "GPGST,120000.00,0.0,0.0,0.0,0.0,0.0,0.0,0.0"
    p.feed(RawEvent(T0 + S // 10, "gps", f"${text}*{enc.checksum(text)}\r\n".encode()))
    out = p.feed(RawEvent(T0 + S, "gps", gga_at(0.0, 0.0) + hdt))
    (fix,) = [o.payload for o in out if o.topic == "/gnss/gps/fix"]
    assert fix["position_covariance_type"] == 0 and fix["position_covariance"] == [0.0] * 9  # UNKNOWN
    (m,) = [o.payload for o in out if o.topic == "/dp/measurement"]
    assert m.get("covariance_ne_m2") is None and p.fusion.position_covariance_ne(T0 + S) is None
    assert not p.counters["gps"].rejected
