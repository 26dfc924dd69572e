"""Zenoh endpoints taken apart (`gateway.config.endpoints`): one reading for the start-up notes and the
bus's link check."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gateway.config.endpoints import endpoint_parts, is_ip, is_loopback


@pytest.mark.parametrize(
    ("endpoint", "parts", "loopback"),
    [
        ("tcp/127.0.0.1:7447", ("tcp", "127.0.0.1", "7447"), True),
        ("tcp/[::1]:7447", ("tcp", "::1", "7447"), True),
        ("udp/localhost:7447?iface=lo", ("udp", "localhost", "7447"), True),
        ("tcp/192.168.1.10:7447#rx_buffer_size=65536", ("tcp", "192.168.1.10", "7447"), False),
        ("tcp/[fe80::1%eth0]:7447", ("tcp", "fe80::1%eth0", "7447"), False),
        ("tls/router.example.org:7447", ("tls", "router.example.org", "7447"), False),
        ("tcp/0.0.0.0:0", ("tcp", "0.0.0.0", "0"), False),  # every interface: not loopback only
        ("tcp/127.1.2.3:7447", ("tcp", "127.1.2.3", "7447"), True),  # all of 127/8 is loopback
        ("nonsense", ("nonsense", "", ""), False),
    ],
)
def test_an_endpoint_taken_apart(endpoint: str, parts: tuple[str, str, str], loopback: bool) -> None:
    assert endpoint_parts(endpoint) == parts
    assert is_loopback(endpoint) is loopback


def test_an_ip_is_told_from_a_name() -> None:
    assert is_ip("10.0.0.1") and is_ip("::1") and not is_ip("localhost") and not is_ip("")


@given(st.text(max_size=60))
def test_any_text_is_taken_apart_without_raising(endpoint: str) -> None:
    proto, host, port = endpoint_parts(endpoint)
    assert isinstance(is_loopback(endpoint), bool)
    # every part is a piece of what was written, in order
    assert endpoint.startswith(proto) and host in endpoint and port in endpoint
    assert not any(c in part for part in (proto, host, port) for c in "?#")
