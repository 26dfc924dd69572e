"""Record layout facts from the MCAP specification that both the writer and the reader rely on."""

from __future__ import annotations

MAGIC = b"\x89MCAP0\r\n"
"""Leading and trailing magic of every MCAP file."""
RECORD_HEADER = 1 + 8
"""Every record starts with opcode (u8) and body length (u64)."""
OPCODE_FOOTER = 0x02
OPCODE_DATA_END = 0x0F
OPCODE_METADATA = 0x0C
