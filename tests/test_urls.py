"""`wire.urls`: the one link-URL grammar of the config, the gateway's sources and the simulator's sinks."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wire.urls import (
    SINK_OPTIONS,
    SOURCE_OPTIONS,
    Endpoint,
    UrlError,
    file_rate,
    parse_url,
    serial_settings,
)

# --- what each spelling means ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "serial:///dev/ttyUSB0?baud=4800",
            Endpoint("serial", path="/dev/ttyUSB0", options=(("baud", "4800"),)),
        ),
        ("pty:///tmp/dpgw-gps", Endpoint("pty", path="/tmp/dpgw-gps")),
        ("udp://0.0.0.0:10110", Endpoint("udp", host="0.0.0.0", port=10110)),
        ("udp://[::1]:10110", Endpoint("udp", host="::1", port=10110)),
        ("tcp://gps.local:10110", Endpoint("tcp", host="gps.local", port=10110)),
        ("tcp-listen://:5760", Endpoint("tcp-listen", host="", port=5760)),
        (
            "file:///data/run1.nmea?rate=fast",
            Endpoint("file", path="/data/run1.nmea", options=(("rate", "fast"),)),
        ),
        # pymavlink connection strings map onto the same endpoints
        ("udpin:0.0.0.0:14550", Endpoint("udp", host="0.0.0.0", port=14550, pymavlink="udpin")),
        (
            "udpout:10.0.0.2:14550",
            Endpoint("udp", port=0, options=(("target", "10.0.0.2:14550"),), pymavlink="udpout"),
        ),
        ("tcp:127.0.0.1:5760", Endpoint("tcp", host="127.0.0.1", port=5760, pymavlink="tcp")),
        ("tcpin:0.0.0.0:5760", Endpoint("tcp-listen", host="0.0.0.0", port=5760, pymavlink="tcpin")),
        (
            "/dev/ttyACM0,57600",
            Endpoint("serial", path="/dev/ttyACM0", options=(("baud", "57600"),), pymavlink="device"),
        ),
        (
            "serial:/dev/ttyACM0:57600",
            Endpoint("serial", path="/dev/ttyACM0", options=(("baud", "57600"),), pymavlink="serial"),
        ),
    ],
)
def test_each_spelling_parses_to_its_endpoint(text: str, expected: Endpoint) -> None:
    assert parse_url(text, pymavlink=True) == expected


def test_tcp_is_a_client_and_tcp_listen_a_server_on_both_sides() -> None:
    assert not parse_url("tcp://10.0.0.1:2000").listens
    assert parse_url("tcp-listen://0.0.0.0:2000").listens
    assert parse_url("tcp-listen://0.0.0.0:2000", options=SINK_OPTIONS).scheme == "tcp-listen"


def test_the_old_simulator_server_spelling_names_the_new_one() -> None:
    with pytest.raises(UrlError) as info:
        parse_url("tcp://0.0.0.0:10110", options=SINK_OPTIONS)
    assert "tcp-listen://0.0.0.0:10110" in str(info.value)
    assert "old spelling" in str(info.value)


def test_relative_files_only_where_allowed() -> None:
    assert parse_url("file:logs/x.nmea", relative_files=True) == Endpoint("file", path="logs/x.nmea")
    with pytest.raises(UrlError, match=r"did you mean file://logs/x\.nmea"):
        parse_url("file:logs/x.nmea")
    assert parse_url("out/x.nmea", options=SINK_OPTIONS, bare_path="file") == Endpoint(
        "file", path="out/x.nmea"
    )


def test_typed_option_values() -> None:
    s = serial_settings(parse_url("serial:///dev/ttyS1?baud=38400&bytesize=7&parity=even&stopbits=1.5"))
    assert (s.baud, s.bytesize, s.parity, s.stopbits) == (38400, 7, "E", 1.5)
    assert serial_settings(parse_url("/dev/ttyACM0", pymavlink=True), 115200).baud == 115200
    assert file_rate(parse_url("file:///x?rate=12.5")) == 12.5
    assert file_rate(parse_url("file:///x")) == "realtime"


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("", "empty URL"),
        ("serail:///dev/ttyUSB0", "unknown transport 'serail', did you mean serial://?"),
        ("serial://dev/ttyUSB0", "three slashes: serial:///dev/ttyUSB0"),
        ("tcp-listen:0.0.0.0:10110", "did you mean tcp-listen://0.0.0.0:10110?"),
        (
            "192.168.1.5:10110",
            "no transport given (expected udp://192.168.1.5:10110 or tcp://192.168.1.5:10110)",
        ),
        ("serial:///dev/ttyUSB0?buad=4800", "unknown option 'buad' for serial, did you mean 'baud'?"),
        ("udp://0.0.0.0:70000", "port 70000 is out of range"),
        ("udp://127.0.0.1:201100", "port 201100 is out of range"),  # (six digits: was "not HOST:PORT")
        ("udp://0.0.0.0", "'0.0.0.0' is not HOST:PORT"),
        (
            "tcp://:2000",
            "no host to connect to (expected tcp://HOST:2000 (a client), or tcp-listen://0.0.0.0:2000",
        ),
        ("tcp://127.0.0.1:0", "port 0 is out of range"),
        ("udpout::14550", "no host to send to"),
        ("udpbcast:1.2.3.4:14550", "unknown transport 'udpbcast'"),
        ("gps.nmea", "not a URL"),
        ("udp://1.2.3.4:5#x", "unexpected '#x'"),
        ("udp://1.2.3.4:5 6", "spaces"),
        ("udp://127.0.0.1:10110?iface=eth0", "iface is for multicast groups"),
        ("udp://:0?target=nowhere", "'nowhere' is not HOST:PORT"),
        ("serial:///dev/ttyUSB0?baud=4800&baud=9600", "option 'baud' given 2 times"),
        ("tcp://h:1/path", "unexpected path '/path'"),
    ],
)
def test_rejects_with_a_clear_message(text: str, fragment: str) -> None:
    with pytest.raises(UrlError) as info:
        parse_url(text, pymavlink=True)
    assert fragment in str(info.value)


# --- properties ----------------------------------------------------------------------------------------

_hosts = st.one_of(
    st.just(""),
    st.from_regex(r"[a-z][a-z0-9-]{0,12}(\.[a-z][a-z0-9-]{0,8}){0,2}", fullmatch=True),
    st.ip_addresses(v=4).map(str),
    st.ip_addresses(v=6).map(str),
)
_paths = st.from_regex(r"(/[A-Za-z0-9._ %~+-]{1,12}){1,4}", fullmatch=True)
_values = st.from_regex(r"[A-Za-z0-9.:_-]{1,10}", fullmatch=True)


@st.composite
def endpoints(draw: st.DrawFn) -> Endpoint:
    scheme = draw(st.sampled_from(["serial", "pty", "udp", "tcp", "tcp-listen", "file"]))
    keys = (
        draw(st.lists(st.sampled_from(["baud", "parity"]), unique=True))
        if scheme in ("serial", "pty")
        else []
    )
    if scheme == "file":
        keys = draw(st.lists(st.just("rate"), max_size=1))
    options = tuple((k, draw(_values)) for k in keys)
    if scheme in ("serial", "pty", "file"):
        return Endpoint(scheme, path=draw(_paths), options=options)
    host = draw(_hosts)
    if scheme == "tcp" and not host:
        host = "localhost"
    port = draw(st.integers(1 if scheme == "tcp" else 0, 65535))
    return Endpoint(scheme, host=host, port=port)


@settings(max_examples=300, deadline=None)
@given(endpoints())
def test_format_then_parse_is_the_identity(endpoint: Endpoint) -> None:
    assert parse_url(endpoint.format()) == endpoint


@settings(max_examples=300, deadline=None)
@given(
    st.text(max_size=60)
    | st.from_regex(r"(udp|tcp|tcp-listen|serial|file|pty|udpin|tcpin|udpout):/{0,3}[\w.:?=&/\[\]#-]{0,30}")
)
def test_any_text_is_an_endpoint_or_a_url_error(text: str) -> None:
    for options in (SOURCE_OPTIONS, SINK_OPTIONS):
        try:
            endpoint = parse_url(text, options=options, pymavlink=options is SOURCE_OPTIONS)
        except UrlError as exc:
            assert exc.problem  # every refusal says what is wrong
        else:
            assert endpoint.scheme in options
            # the canonical form means the same thing
            again = parse_url(endpoint.format(), options=options)
            assert (again.scheme, again.host, again.port, again.path) == (
                endpoint.scheme,
                endpoint.host,
                endpoint.port,
                endpoint.path,
            )


@pytest.mark.parametrize(
    ("text", "size"),
    [("", 4 * 1024 * 1024), ("?rcvbuf=65536", 65536), ("?rcvbuf=8M", 8 * 1024**2), ("?rcvbuf=64k", 65536)],
)
def test_udp_receive_buffer_option(text: str, size: int) -> None:
    from wire.urls import receive_buffer

    assert receive_buffer(parse_url("udp://:10110" + text, options=SOURCE_OPTIONS), 4 * 1024 * 1024) == size


@pytest.mark.parametrize("bad", ["12", "2G", "lots", "-5", "4096.5"])
def test_udp_receive_buffer_refuses_what_is_not_a_size(bad: str) -> None:
    from wire.urls import receive_buffer

    with pytest.raises(UrlError, match="rcvbuf"):
        receive_buffer(parse_url(f"udp://:10110?rcvbuf={bad}", options=SOURCE_OPTIONS), 1)
