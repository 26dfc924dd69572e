"""Roll/pitch lever-arm compensation from a motion reference unit (MRU): the simulator's MRU, the fusion's
inverse of the simulator's antenna, the pipeline's role ``attitude`` (fresh → R_zyx(φ, θ, ψ), stale →
heading only, said and counted), its config, and the closed loop on a 25 m mast (the wave-frequency antenna
motion removed, the observer's LF error smaller)."""

from __future__ import annotations

import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.config import ConfigError, parse_config
from gateway.fusion import Fusion
from gateway.pipeline import Pipeline, PipelineSpec, RawEvent
from observers.kinematics import lever_arm_ned
from observers.vessel import load_vessel
from simulator.clock import SimEpoch
from simulator.faults import Fault, FaultSchedule
from simulator.sensors import Mru, MruConfig, ShipState, antenna_ned
from wire.codecs import nmea_encode as enc
from wire.codecs.nmea import Attitude, decode
from wire.geodesy import LocalFrame

S = 1_000_000_000
T0 = 1_780_000_000 * S
DATUM = (59.4, 10.5)
ARM = (10.0, 2.0, -25.0)


def angle_diff(a: float, b: float) -> float:
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


# ---------------------------------------------------------------------------------------------- kinematics


@given(
    psi=st.floats(-math.pi, math.pi),
    phi=st.floats(-0.5, 0.5),
    theta=st.floats(-0.3, 0.3),
    arm=st.tuples(st.floats(-80, 80), st.floats(-20, 20), st.floats(-40, 10)),
)
def test_lever_arm_rotation_is_the_matrix_r_zyx(
    psi: float, phi: float, theta: float, arm: tuple[float, float, float]
) -> None:
    """`lever_arm_ned` is R_z(ψ) R_y(θ) R_x(φ) of Fossen (2021) eq. 2.18, written as matrices."""
    cf, sf, ct, st_, cp, sp = (math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta),
                               math.cos(psi), math.sin(psi))  # fmt: skip
    rx = np.array([[1, 0, 0], [0, cf, -sf], [0, sf, cf]])
    ry = np.array([[ct, 0, st_], [0, 1, 0], [-st_, 0, ct]])
    rz = np.array([[cp, -sp, 0], [sp, cp, 0], [0, 0, 1]])
    np.testing.assert_allclose(lever_arm_ned(psi, phi, theta, *arm), rz @ ry @ rx @ np.array(arm), atol=1e-9)


def test_signs_starboard_down_moves_a_mast_top_to_starboard_bow_up_moves_it_aft() -> None:
    top = (0.0, 0.0, -20.0)  # 20 m above the reference point, heading north
    dn, de, _ = lever_arm_ned(0.0, math.radians(1.0), 0.0, *top)
    assert de == pytest.approx(20 * math.sin(math.radians(1.0))) and abs(dn) < 1e-12  # 0.35 m to starboard
    dn, de, _ = lever_arm_ned(0.0, 0.0, math.radians(1.0), *top)
    assert dn == pytest.approx(-20 * math.sin(math.radians(1.0))) and abs(de) < 1e-12  # bow up: mast aft


# ---------------------------------------------------------------------------------------------- fusion


@settings(max_examples=60, deadline=None)
@given(
    psi=st.floats(-math.pi, math.pi),
    phi=st.floats(-0.3, 0.3),
    theta=st.floats(-0.2, 0.2),
    north=st.floats(-500, 500),
    east=st.floats(-500, 500),
    arm=st.tuples(st.floats(-60, 60), st.floats(-15, 15), st.floats(-35, 5)),
)
def test_a_fix_and_an_attitude_give_the_reference_point_back(
    psi: float, phi: float, theta: float, north: float, east: float, arm: tuple[float, float, float]
) -> None:
    """The fusion's compensation is the inverse of the simulator's antenna (`antenna_ned`): the same
    rotation, so the reference point comes back to the geodesy's round trip (well under a millimetre)."""
    frame = LocalFrame(*DATUM, 0.0)
    ant = antenna_ned([north, east, psi], arm, [0.0, phi, theta])
    lat, lon, _ = frame.to_geodetic(float(ant[0]), float(ant[1]), 0.0)
    f = Fusion(load_vessel("mss_supply"), datum=frame)
    f.add_heading(T0, psi, "gyro", 1, 2 * S)
    f.add_attitude(T0, phi, theta, "mru", 1, S)
    ref = f.reference_position(T0 + S // 100, lat, lon, arm)
    assert ref is not None
    if any(arm):
        assert f.last_compensation == "attitude" and f.attitude_source == "mru"
    np.testing.assert_allclose(ref, [north, east], atol=1e-6)
    # heading only (no attitude): off by the arm's roll/pitch motion, as the gateway was before
    g = Fusion(load_vessel("mss_supply"), datum=frame)
    g.add_heading(T0, psi, "gyro", 1, 2 * S)
    ref0 = g.reference_position(T0, lat, lon, arm)
    assert ref0 is not None and g.last_compensation == ("heading" if arm[0] or arm[1] or arm[2] else "")
    exact = antenna_ned([north, east, psi], arm, [0.0, 0.0, 0.0])
    np.testing.assert_allclose(np.array(ref0) - (ant[:2] - exact[:2]), [north, east], atol=1e-6)


def test_attitude_pairs_with_the_fix_by_time_and_goes_stale() -> None:
    f = Fusion(load_vessel("mss_supply"))
    for k in range(10):  # 10 Hz, roll = k mrad
        f.add_attitude(T0 + k * S // 10, k * 1e-3, 0.0, "mru", 1, S // 2)
    hit = f.attitude_at(T0 + 4 * S // 10 + S // 100)
    assert hit is not None and hit[0] == pytest.approx(4e-3)
    assert f.attitude_at(T0 + 9 * S // 10 + S // 2) is not None  # within the timeout of the newest
    assert f.attitude_at(T0 + 9 * S // 10 + S // 2 + 1) is None  # stale
    # a better-ranked source wins while it has a sample within its timeout
    f.add_attitude(T0 + 9 * S // 10, 0.5, 0.0, "mru0", 0, S // 2)
    hit = f.attitude_at(T0 + S)
    assert hit is not None and hit[2] == "mru0"


# ---------------------------------------------------------------------------------------------- simulator


@pytest.mark.parametrize("sentence", ["PHTRO", "PASHR"])
def test_mru_sends_the_states_roll_and_pitch(sentence: str) -> None:
    epoch = SimEpoch(datetime(2026, 6, 1, 10, tzinfo=UTC))
    cfg = MruConfig(sentence=sentence, rate_hz=20.0)
    typed = Mru(cfg, epoch, np.random.default_rng(7))
    typed.encode = False
    wire = Mru(cfg, epoch, np.random.default_rng(7))
    rolls, errs = [], []
    for k in range(2000):
        t = k / 20.0
        phi, theta = 0.05 * math.sin(0.6 * t), -0.03 * math.cos(0.5 * t)
        state = ShipState(t, np.array([1.0, 2.0, 0.7]), np.zeros(3), attitude=np.array([0.4, phi, theta]))
        (e,) = wire.sample(state)
        (r,) = typed.sample(state)
        assert e.t_emit == pytest.approx(t + cfg.latency_s) and e.data.startswith(f"${sentence},".encode())
        s = decode(e.text.strip())
        assert isinstance(s, Attitude) and s.kind == sentence and s.valid and isinstance(r.record, Attitude)
        # the typed record is what a receiver decodes, unrounded (0.01° on the wire)
        assert abs(s.roll_rad - r.record.roll_rad) <= math.radians(0.005) + 1e-12  # type: ignore[operator]
        assert abs(s.pitch_rad - r.record.pitch_rad) <= math.radians(0.005) + 1e-12  # type: ignore[operator]
        if sentence == "PASHR":
            assert s.heave_up_m == pytest.approx(-0.4, abs=0.005)
            assert angle_diff(s.heading_rad or 0.0, 0.7) < math.radians(0.5)
        errs.append((r.record.roll_rad - phi, r.record.pitch_rad - theta))
        rolls.append(s.roll_rad)
    errs_a = np.array(errs)
    assert np.std(errs_a, axis=0) == pytest.approx([cfg.sigma_rad] * 2, rel=0.1)  # 2000 samples: ±3 %
    assert abs(np.mean(errs_a)) < 3 * cfg.sigma_rad / math.sqrt(1000)


def test_mru_dropout_silences_it() -> None:
    faults = FaultSchedule([Fault("dropout", "mru1", 1.0, 2.0)])
    mru = Mru(MruConfig(), SimEpoch(datetime(2026, 6, 1, tzinfo=UTC)), np.random.default_rng(1), faults)
    sent = [bool(mru.sample(ShipState(k / 10, np.zeros(3), np.zeros(3)))) for k in range(40)]
    assert sent[:10] == [True] * 10 and not any(sent[10:20]) and all(sent[21:])


def test_mru_config_is_checked() -> None:
    with pytest.raises(ValueError, match=r"MruConfig\.sentence"):
        MruConfig(sentence="HDT")
    with pytest.raises(ValueError, match=r"MruConfig\.rate_hz"):
        MruConfig(rate_hz=0.0)


# ---------------------------------------------------------------------------------------------- pipeline


def nmea_src(name: str, roles: list[str], **kw: Any) -> dict[str, Any]:
    return {"name": name, "url": "udp://127.0.0.1:0", "protocol": "nmea", "roles": roles, **kw}


def tables(sources: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "vessel": {"name": "mss_supply"},
        "datum": {"lat_deg": DATUM[0], "lon_deg": DATUM[1]},
        "sources": sources,
        "observer": {"wave_period_s": 8.0},
        "integrity": {"freeze_s": 600.0, "heading_freeze_s": 600.0},
        "log": {"path": ""},
    }


def pipeline(with_mru: bool = True) -> Pipeline:
    sources = [nmea_src("gps", ["position"], lever_arm_m=list(ARM)), nmea_src("gyro", ["heading"])]
    if with_mru:
        sources.append(nmea_src("mru", ["attitude"], timeout_s=0.5))
    return Pipeline(PipelineSpec.from_config(parse_config(tables(sources), base_dir=Path.cwd())))


def gga_of_antenna(psi: float, phi: float, theta: float, ref: tuple[float, float]) -> bytes:
    ant = antenna_ned([ref[0], ref[1], psi], ARM, [0.0, phi, theta])
    lat, lon, _ = LocalFrame(*DATUM).to_geodetic(float(ant[0]), float(ant[1]), 0.0)
    return enc.gga("GP", datetime(2026, 6, 1, tzinfo=UTC), lat, lon, 2, 12, 0.8, 20.0).encode()


def measurements(out: list[Any]) -> list[dict[str, Any]]:
    return [o.payload for o in out if o.topic == "/dp/measurement"]


def lever_arm_events(p: Pipeline, out: list[Any], now_ns: int) -> list[str]:
    """The lever-arm events said in the statuses published in ``out`` and in the status at ``now_ns``."""
    statuses = [o.payload for o in out if o.topic == "/dp/status"] + [p.status(now_ns).payload]
    return [e for st in statuses for e in st.get("events", []) if "lever-arm" in e]


def test_pipeline_compensates_roll_and_pitch_with_a_fresh_mru_and_heading_only_when_stale() -> None:
    """A PHTRO before each fix: the measured position is the reference point (to the sentences'
    rounding: 2 mm of GGA, 0.005° × 25 m of PHTRO). The MRU falls silent: the next fixes are compensated
    by heading alone (off by the mast's roll and pitch motion, no crash), counted per position source;
    the status says so once, and once again when the MRU is back."""
    p = pipeline()
    psi, phi, theta, ref = math.radians(30.0), math.radians(3.0), math.radians(-2.0), (100.0, 50.0)
    out: list[Any] = []
    t = T0
    for _ in range(4):
        t += S // 2
        out += p.feed(RawEvent(t, "gyro", enc.hdt("HE", psi).encode()))
        out += p.feed(RawEvent(t + 1000, "mru", enc.phtro(phi, theta).encode()))
        out += p.feed(RawEvent(t + 2000, "gps", gga_of_antenna(psi, phi, theta, ref)))
    meas = measurements(out)[-1]
    np.testing.assert_allclose(meas["eta"][:2], ref, atol=0.005)
    assert p.lever_arm_compensation == {"attitude": 4}
    on = ["lever-arm compensation: roll and pitch from mru (MRU) on"]
    assert lever_arm_events(p, out, t + 3000) == on
    # the MRU stops: stale after its 0.5 s timeout
    out = []
    for _ in range(3):
        t += S // 2
        out += p.feed(RawEvent(t, "gyro", enc.hdt("HE", psi).encode()))
        out += p.feed(RawEvent(t + 2000, "gps", gga_of_antenna(psi, phi, theta, ref)))
    meas = measurements(out)[-1]
    heading_only = antenna_ned([*ref, psi], ARM, [0.0, phi, theta])[:2] - np.array(
        lever_arm_ned(psi, 0.0, 0.0, *ARM)[:2]
    )
    np.testing.assert_allclose(meas["eta"][:2], heading_only, atol=0.005)
    assert np.hypot(*(heading_only - np.array(ref))) > 1.0  # (what the MRU was taking out)
    assert p.lever_arm_compensation == {"attitude": 4, "heading": 3}
    assert lever_arm_events(p, out, t + 3000) == [
        "lever-arm compensation: heading only (no fresh attitude from mru)"
    ]
    status = p.status(t + 3000).payload
    assert status["sources"]["gps"]["warnings"]["lever_arm_heading_only"] == 3  # (used: not a reject)
    assert "lever_arm_heading_only" not in status["sources"]["gps"]["rejected"]
    assert any("source mru: stale" in a for a in status["alarms"])
    # back
    t += S // 2
    out = p.feed(RawEvent(t, "gyro", enc.hdt("HE", psi).encode()))
    out += p.feed(RawEvent(t + 1000, "mru", enc.phtro(phi, theta).encode()))
    out += p.feed(RawEvent(t + 2000, "gps", gga_of_antenna(psi, phi, theta, ref)))
    assert lever_arm_events(p, out, t + 3000) == on


def test_without_an_attitude_source_nothing_changes_and_nothing_is_said() -> None:
    p = pipeline(with_mru=False)
    psi, ref = 0.3, (10.0, -5.0)
    out: list[Any] = []
    for k in range(3):
        t = T0 + k * S // 2
        out += p.feed(RawEvent(t, "gyro", enc.hdt("HE", psi).encode()))
        out += p.feed(RawEvent(t + 1000, "mru", enc.phtro(0.1, 0.1).encode()))  # (no such source: ignored)
        out += p.feed(RawEvent(t + 2000, "gps", gga_of_antenna(psi, 0.0, 0.0, ref)))
    np.testing.assert_allclose(measurements(out)[-1]["eta"][:2], ref, atol=0.005)
    assert not p.lever_arm_compensation and not lever_arm_events(p, out, T0 + 2 * S)
    assert "warnings" not in p.status(T0 + 2 * S).payload["sources"]["gps"]  # (left out while empty)


def test_bad_and_empty_attitude_sentences_are_counted_not_used() -> None:
    p = pipeline()
    p.feed(RawEvent(T0, "gyro", enc.hdt("HE", 0.0).encode()))
    p.feed(RawEvent(T0 + 1, "mru", enc.phtro(None, None).encode()))  # no measurement
    bad = "PHTRO,2.00,X,3.00,T"
    p.feed(RawEvent(T0 + 2, "mru", f"${bad}*{enc.checksum(bad)}\r\n".encode()))
    p.feed(RawEvent(T0 + 3, "gps", gga_of_antenna(0.0, 0.0, 0.0, (0.0, 0.0))))
    rejected = p.counters["mru"].rejected
    assert rejected["attitude_invalid"] == 1 and rejected["bad_field"] == 1
    assert p.fusion.last_compensation == "heading"


# ---------------------------------------------------------------------------------------------- config


def config_of(*extra: dict[str, Any], gps: dict[str, Any] | None = None) -> Any:
    base = [gps or nmea_src("gps", ["position"]), nmea_src("gyro", ["heading"])]
    return parse_config(tables([*base, *extra]), base_dir=Path.cwd())


def test_config_role_attitude_is_nmea_only_and_carries_no_lever_arm() -> None:
    ok = config_of(nmea_src("mru", ["attitude"]), gps=nmea_src("gps", ["position"], lever_arm_m=list(ARM)))
    assert ok.source("mru").roles == ("attitude",)
    assert ok.source("gps").lever_arm_m == ARM  # the position source's arm is the one compensated
    mavlink = {"name": "m", "url": "udpin:127.0.0.1:0", "protocol": "mavlink", "roles": ["attitude"]}
    with pytest.raises(ConfigError, match=r'role "attitude" is not available for protocol "mavlink"'):
        config_of(mavlink)
    with pytest.raises(ConfigError, match="lever_arm_m"):
        config_of(nmea_src("mru", ["attitude"], lever_arm_m=[0, 0, 0]))
    with pytest.raises(ConfigError, match="attitud"):
        config_of(nmea_src("mru", ["attitud"]))


# ---------------------------------------------------------------------------------------------- closed loop


def test_closed_loop_on_a_25_m_mast_the_mru_removes_the_wave_motion_and_improves_the_estimate() -> None:
    """`torsetnes_2004_mast` (Hs 6 m, roll and pitch 2-3° 1σ, antenna 25 m up), the same seeds with and
    without the MRU source in the gateway's config (bench/bench_mru_lever_arm.py prints the figures):
    the measured position minus the true reference point loses ≥ 10 dB in the wave band (measured 15-17
    dB), and the observer's LF position error is smaller on every seed."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "bench_mru", Path(__file__).resolve().parents[1] / "bench" / "bench_mru_lever_arm.py"
    )
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    for seed in (1, 2):
        on, off = bench.one(seed, 600.0, True), bench.one(seed, 600.0, False)
        reduction_db = 10 * math.log10(off["wave_band_power_m2"] / on["wave_band_power_m2"])
        assert reduction_db >= 10.0, (seed, on, off)
        assert on["fix_rms_m"] < 0.6 < 1.0 < off["fix_rms_m"], (seed, on, off)  # 0.3 m σ per axis: 0.42
        assert on["lf_rms_m"] < off["lf_rms_m"], (seed, on, off)


def test_a_fix_without_a_lever_arm_is_not_counted_as_compensated() -> None:
    """Two receivers, one on the mast and one at the reference point (no lever arm), the MRU silent: the
    mast's fixes are compensated by heading alone (counted, a warning); the other's need no compensation
    and are neither counted nor warned about (not the previous fix's way carried over to it)."""
    sources = [
        nmea_src("gps", ["position"], lever_arm_m=list(ARM)),
        nmea_src("gps2", ["position"], priority=2),
        nmea_src("gyro", ["heading"]),
        nmea_src("mru", ["attitude"], timeout_s=0.5),
    ]
    p = Pipeline(PipelineSpec.from_config(parse_config(tables(sources), base_dir=Path.cwd())))
    psi, ref = 0.3, (10.0, -5.0)
    for k in range(3):
        t = T0 + k * S // 2
        p.feed(RawEvent(t, "gyro", enc.hdt("HE", psi).encode()))
        p.feed(RawEvent(t + 1000, "gps", gga_of_antenna(psi, 0.0, 0.0, ref)))
        lat, lon, _ = LocalFrame(*DATUM).to_geodetic(*ref, 0.0)
        gga = enc.gga("GP", datetime(2026, 6, 1, tzinfo=UTC), lat, lon, 2, 12, 0.8, 20.0)
        p.feed(RawEvent(t + 2000, "gps2", gga.encode()))
    assert p.lever_arm_compensation == {"heading": 3}
    sources_status = p.status(T0 + 2 * S).payload["sources"]
    assert sources_status["gps"]["warnings"]["lever_arm_heading_only"] == 3
    assert "warnings" not in sources_status["gps2"]
