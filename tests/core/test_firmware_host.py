"""The firmware's protocol code (firmware/src/proto.c) on the host, held against labcli.core.wire.

``make -C firmware test`` runs the C unit tests (known answers: the protocol
document's example line, the commands and their replies, the rate arithmetic,
the oversampling scale).  Here the same C code, behind ``proto_tool``, meets
the host's reference codec on random inputs: every line the firmware formats
parses back to the same frame with labcli's reference parser and is the very
line labcli's own formatter makes; checksums agree on random bytes; whatever
a host sends, the firmware's answer is one protocol reply line.
"""

from __future__ import annotations

import subprocess

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.firmware_build import make, need_avr_tools, need_host_compiler

from labcli.core.wire import Frame, Reply, checksum, format_frame, parse_line

U32 = st.integers(0, 2**32 - 1)


@pytest.fixture(scope="module")
def host_build(tmp_path_factory):
    need_host_compiler()
    build = tmp_path_factory.mktemp("firmware-host")
    out = make(build, "test")
    return build, out


class ProtoTool:
    """firmware/test/proto_tool.c: one request line in, one answer line out."""

    def __init__(self, path) -> None:
        self.proc = subprocess.Popen([str(path)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)

    def ask(self, request: str) -> str:
        self.proc.stdin.write(request + "\n")
        self.proc.stdin.flush()
        return self.proc.stdout.readline()

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(5)


@pytest.fixture(scope="module")
def tool(host_build):
    t = ProtoTool(host_build[0] / "host" / "proto_tool")
    yield t
    t.close()


def test_c_unit_tests_pass(host_build):
    out = host_build[1]
    assert "checks passed" in out and "failed" not in out


@settings(max_examples=300, deadline=None)
@given(seq=U32, t_us=U32, values=st.lists(st.integers(0, 65535), min_size=1, max_size=8))
def test_c_frames_parse_with_the_reference_parser(tool, seq, t_us, values):
    line = tool.ask(f"F {seq} {t_us} " + " ".join(map(str, values))).encode("ascii")
    assert parse_line(line, len(values)) == Frame(seq, t_us, tuple(values))
    assert line == format_frame(seq, t_us, values)


@settings(max_examples=300, deadline=None)
@given(payload=st.binary(min_size=0, max_size=255))
def test_c_checksum_agrees_with_labcli(tool, payload):
    assert int(tool.ask("C " + payload.hex()), 16) == checksum(payload)


def test_c_checksum_flags_every_single_bit_error(tool):
    line = tool.ask("F 123 4567 1556 1560 1549 1551 2048 2047").encode()
    body = line[1 : line.index(b"*")]
    for i in range(len(body)):
        for bit in range(8):
            spoiled = bytearray(body)
            spoiled[i] ^= 1 << bit
            assert int(tool.ask("C " + spoiled.hex()), 16) != int(line[-3:-1], 16)


@settings(max_examples=300, deadline=None)
@given(text=st.text(st.characters(min_codepoint=1, max_codepoint=255, blacklist_characters="\n"), max_size=62))
def test_any_command_line_gets_one_reply_line_or_none(tool, text):
    action, reply_hex = tool.ask("L " + text.encode("latin-1").hex()).split(" ")
    reply = bytes.fromhex(reply_hex.strip())
    if not text.strip(" \t"):
        assert (action, reply) == ("0", b"")
        return
    assert reply.endswith(b"\n") and reply.count(b"\n") == 1
    assert isinstance(parse_line(reply), Reply)  # never noise to a host


@settings(max_examples=200, deadline=None)
@given(hz=st.decimals(min_value=1, max_value=200, places=3))
def test_rate_replies_the_rate_the_timer_makes(tool, hz):
    action, reply_hex = tool.ask("L " + f"RATE {hz}".encode().hex()).split(" ")
    reply = bytes.fromhex(reply_hex.strip()).decode()
    assert action == "2" and reply.startswith("OK RATE ")
    ticks, mhz, n_sub, top, extra, ps = map(int, tool.ask(f"R {round(hz * 1000)}").split())
    actual = float(reply.split()[2])
    assert actual == pytest.approx(mhz / 1000, abs=5e-4)
    assert actual == pytest.approx(2e6 / ticks, abs=5e-4)  # 0.5 us ticks at 16 MHz
    assert abs(2e6 / ticks - float(hz)) <= float(hz) ** 2 / 2e6 * 0.5 + 1e-9  # nearest whole tick
    assert (top + 1) * n_sub + extra == ticks and top + 1 + (extra > 0) <= 65536 and extra < n_sub
    # The ADC clock leaves a quarter of the period: 96 conversions of 13 ADC clocks + 64 cycles each.
    assert 96 * ((13 << ps) + 64) * 4 <= ticks * 8 * 3 or ps == 4


def test_firmware_builds_clean_and_fits_the_chip(tmp_path):
    need_avr_tools()
    out = make(tmp_path, "firmware")  # make() asserts there is no warning
    sizes = dict(line.split(":", 1) for line in out.splitlines() if line.startswith(("Program", "Data")))
    program = int(sizes["Program"].split()[0])
    data = int(sizes["Data"].split()[0])
    assert program < 32256 - 512  # flash, the Uno's bootloader (optiboot, 512 bytes) excluded
    assert data < 1024  # static RAM, half of the 2 KiB: the rest is stack
    hex_lines = (tmp_path / "labcli_rig.hex").read_text().splitlines()
    assert hex_lines[-1] == ":00000001FF"  # an Intel HEX file avrdude can flash
