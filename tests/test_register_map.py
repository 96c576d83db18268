"""Register map: byte-exact encoding, word order, and clear errors for malformed lab files."""

import struct
import tomllib
from pathlib import Path

import pytest
from pymodbus.client import AsyncModbusTcpClient

from drivers.errors import RegisterMapError
from drivers.register_map import REQUIRED, default_map_path, load_register_map, parse_register_map

SHIPPED = load_register_map()


def test_shipped_map_has_every_required_register():
    assert set(SHIPPED.holding) >= REQUIRED["holding"]
    assert set(SHIPPED.input) >= REQUIRED["input"]
    assert SHIPPED.protocol_version == 1
    assert SHIPPED.word_order == "big"


@pytest.mark.parametrize("order", ["big", "little"])
@pytest.mark.parametrize("value", [2.5, -1.0e-3, 12345.678, 0.0])
def test_float32_matches_pymodbus_in_both_word_orders(order, value):
    m = parse_register_map(_with_order(order))
    reg = m.holding["amplitude_mm"]
    words = m.encode(reg, value)
    assert words == AsyncModbusTcpClient.convert_to_registers(
        value, AsyncModbusTcpClient.DATATYPE.FLOAT32, word_order=order
    )
    assert m.decode(reg, words) == pytest.approx(struct.unpack(">f", struct.pack(">f", value))[0])


def test_float32_byte_exact():
    reg = SHIPPED.holding["amplitude_mm"]
    assert SHIPPED.encode(reg, 2.5) == [0x4020, 0x0000]
    little = parse_register_map(_with_order("little"))
    assert little.encode(little.holding["amplitude_mm"], 2.5) == [0x0000, 0x4020]
    assert SHIPPED.encode(SHIPPED.input["cycle_count"], 0x12345678) == [0x1234, 0x5678]


def test_encode_many_groups_consecutive_registers_into_one_write():
    runs = SHIPPED.encode_many("holding", {"taper_in_s": 1.0, "amplitude_mm": 2.0, "frequency_hz": 3.0})
    assert runs == [(10, [0x4000, 0, 0x4040, 0]), (22, [0x3F80, 0])]


def test_encode_out_of_range_integer_is_refused():
    with pytest.raises(ValueError, match="command"):
        SHIPPED.encode(SHIPPED.holding["command"], 70000)


def _with_order(order: str) -> dict:
    data = tomllib.loads(default_map_path().read_text())
    data["map"]["word_order"] = order
    return data


def _write_variant(tmp_path: Path, old: str, new: str) -> Path:
    text = default_map_path().read_text()
    assert old in text
    path = tmp_path / "lab_map.toml"
    path.write_text(text.replace(old, new, 1))
    return path


MALFORMED = [
    # (text in the shipped map, replacement, key named in the error, words in the error)
    ('type = "float32"\nunit = "mm"\ndoc = "displacement', 'type = "float64"\nunit = "mm"\ndoc = "x',
     "holding.amplitude_mm.type", "unknown type 'float64'"),
    ("[holding.frequency_hz]\naddress = 12", "[holding.frequency_hz]\naddress = 11",
     "holding.frequency_hz", "overlaps holding.amplitude_mm"),
    ("[input.state]\naddress = 1", "[input.stat]\naddress = 1",
     "input", "missing required registers ['state']"),
    ('word_order = "big"', 'word_order = "middle"', "map.word_order", "must be one of"),
    ("protocol_version = 1", 'protocol_version = "1"', "map.protocol_version", "integer"),
    ("[holding.command]\naddress = 0", "[holding.command]\naddress = -3",
     "holding.command.address", "0..65535"),
    ("[holding.command]\naddress = 0", "[holding.command]\nadress = 0", "holding.command", "unknown keys"),
    ("[map]", "[mapp]", "mapp", "unknown tables"),
]  # fmt: skip


@pytest.mark.parametrize(("old", "new", "key", "words"), MALFORMED)
def test_malformed_lab_maps_name_file_and_key(tmp_path, old, new, key, words):
    path = _write_variant(tmp_path, old, new)
    with pytest.raises(RegisterMapError) as err:
        load_register_map(path)
    message = str(err.value)
    assert str(path) in message
    assert f"[{key}" in message
    assert words in message


@pytest.mark.parametrize("content", [b"\x00\xff\xfe garbage", b"[holding\naddress = ", b"map = 3"])
def test_garbage_files_give_register_map_errors(tmp_path, content):
    path = tmp_path / "garbage.toml"
    path.write_bytes(content)
    with pytest.raises(RegisterMapError, match=r"garbage\.toml"):
        load_register_map(path)


def test_missing_file_is_a_register_map_error(tmp_path):
    with pytest.raises(RegisterMapError, match="cannot read"):
        load_register_map(tmp_path / "nope.toml")
