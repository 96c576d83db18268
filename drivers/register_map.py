"""The actuator controller's register map, loaded from TOML and validated.

The map is data so that a lab can adapt it to its controller without code changes: addresses,
types and word order come from the file; the names the client and the simulated controller use
are fixed (``REQUIRED``). The protocol codes (commands, waveforms, states, flags) are fixed too and
live here as enums.
"""

from __future__ import annotations

import enum
import itertools
import struct
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from drivers.errors import RegisterMapError

#: register types and their width in 16-bit registers
TYPE_WIDTH = {"uint16": 1, "int16": 1, "uint32": 2, "float32": 2}
_STRUCT = {"uint16": "H", "int16": "h", "uint32": "I", "float32": "f"}
TABLES = ("holding", "input")
WORD_ORDERS = ("big", "little")

REQUIRED: dict[str, frozenset[str]] = {
    "holding": frozenset(
        {
            "command", "waveform", "channel_mask", "heartbeat", "watchdog_ms", "amplitude_mm",
            "frequency_hz", "dwell_s", "sweep_start_hz", "sweep_end_hz", "sweep_duration_s",
            "taper_in_s", "taper_out_s", "mean_mm", "displacement_limit_mm", "force_limit_n",
        }
    ),
    "input": frozenset(
        {
            "protocol_version", "state", "interlock_flags", "error_code", "heartbeat_echo",
            "cycle_count", "achieved_amplitude_mm", "actual_displacement_mm", "actual_force_n",
            "frequency_hz", "sample_count",
        }
    ),
}  # fmt: skip
#: Registers a map may leave out, as one capability each: a controller without them lacks it.
#: ``amplitude_update``: the amplitude of a sine dwell changed during its hold; ``sweep_notch``: a
#: sweep's amplitude lowered over a band of its frequencies; ``frequency_update``: a sine dwell's
#: frequency changed during its hold (docs/protocols.md).
OPTIONAL: dict[str, frozenset[str]] = {
    "amplitude_update": frozenset({"amplitude_update_mm", "amplitude_ramp_s"}),
    "sweep_notch": frozenset({"notch_start_hz", "notch_end_hz", "notch_amplitude_mm", "amplitude_ramp_s"}),
    "frequency_update": frozenset({"frequency_update_hz", "amplitude_ramp_s"}),
    "drive_file": frozenset({"drive_rate_hz", "drive_length", "drive_offset", "drive_block"}),
}
#: The input registers a capability of :data:`OPTIONAL` needs beside its holding registers: a drive's
#: upload is checked by what the controller received.
OPTIONAL_INPUTS: dict[str, frozenset[str]] = {"drive_file": frozenset({"drive_loaded", "drive_crc32"})}
#: The registers that hold a block of values rather than one (``count`` in the map), and the count
#: the protocol gives each.
BLOCKS = {"drive_block": 60}
_REGISTER_KEYS = {"address", "type", "unit", "doc", "count"}


class Command(enum.IntEnum):
    """Codes written to the ``command`` register."""

    HYDRAULICS_OFF = 1
    HYDRAULICS_LOW = 2
    HYDRAULICS_HIGH = 3
    START = 4
    STOP = 5
    ESTOP = 6
    RESET_INTERLOCK = 7


class WaveformCode(enum.IntEnum):
    """Codes of the ``waveform`` register."""

    STATIC = 0
    SINE_DWELL = 1
    LINEAR_SWEEP = 2
    LOG_SWEEP = 3
    DRIVE = 4


class ControllerState(enum.IntEnum):
    """Values of the ``state`` input register."""

    OFF = 0
    HYDRAULICS_LOW = 1
    HYDRAULICS_HIGH = 2
    RUNNING = 3
    TAPERING = 4
    INTERLOCK = 5
    ESTOP = 6


class InterlockFlag(enum.IntFlag):
    """Bits of the ``interlock_flags`` input register."""

    DISPLACEMENT = 1
    FORCE = 2
    WATCHDOG = 4
    ESTOP = 8


class ErrorCode(enum.IntEnum):
    """Values of the ``error_code`` input register: why the last write was refused."""

    NONE = 0
    UNKNOWN_COMMAND = 1
    NOT_ALLOWED_IN_STATE = 2
    INVALID_SETPOINT = 3


#: the controller's states in which the actuator moves (an excitation runs or tapers out)
MOVING_STATES = frozenset({ControllerState.RUNNING, ControllerState.TAPERING})

#: servo channels of the controller: bit i of ``channel_mask`` drives post i + 1
CONTROLLER_CHANNELS = 4
#: every post of a four-post rig, driven together
ALL_POSTS = (1 << CONTROLLER_CHANNELS) - 1

#: the only Modbus function codes the controller serves: read holding, read input, write single,
#: write multiple registers (any other answers ILLEGAL_FUNCTION)
FC_READ_HOLDING, FC_READ_INPUT, FC_WRITE_SINGLE, FC_WRITE_MULTIPLE = 3, 4, 6, 16
#: quantity limits of the Modbus specification (registers per read, per write multiple)
MAX_READ_QUANTITY = 125
MAX_WRITE_QUANTITY = 123


class ModbusExceptionCode(enum.IntEnum):
    """The Modbus exception codes the controller answers with."""

    ILLEGAL_FUNCTION = 1
    ILLEGAL_ADDRESS = 2
    ILLEGAL_VALUE = 3
    DEVICE_FAILURE = 4
    DEVICE_BUSY = 6
    GATEWAY_NO_RESPONSE = 0x0B


#: the exception reply by which the controller refuses a write, per reason in ``error_code``
REFUSAL_EXCEPTION: dict[ErrorCode, ModbusExceptionCode] = {
    ErrorCode.UNKNOWN_COMMAND: ModbusExceptionCode.ILLEGAL_VALUE,
    ErrorCode.INVALID_SETPOINT: ModbusExceptionCode.ILLEGAL_VALUE,
    ErrorCode.NOT_ALLOWED_IN_STATE: ModbusExceptionCode.DEVICE_BUSY,
}
#: exception codes that mean "refused, the reason is in error_code" (any other is a device failure)
REFUSAL_CODES = frozenset(REFUSAL_EXCEPTION.values())


@dataclass(frozen=True)
class Register:
    """One named value: ``width`` consecutive registers from ``address`` in ``table``."""

    table: str
    name: str
    address: int
    type: str
    unit: str = ""
    doc: str = ""
    count: int = 1

    @property
    def width(self) -> int:
        """Registers it occupies: its type's width, ``count`` times for a block."""
        return TYPE_WIDTH[self.type] * self.count


@dataclass(frozen=True)
class RegisterMap:
    """A validated register map: named registers of the holding and input tables and the word order."""

    name: str
    protocol_version: int
    word_order: str
    device_id: int
    holding: Mapping[str, Register]
    input: Mapping[str, Register]
    source: str = "<built-in>"

    def table(self, table: str) -> Mapping[str, Register]:
        return self.holding if table == "holding" else self.input

    @property
    def amplitude_updates(self) -> bool:
        """Whether the controller takes a new amplitude during a sine dwell's hold (the map names
        the registers of :data:`OPTIONAL` ``amplitude_update``)."""
        return OPTIONAL["amplitude_update"] <= self.holding.keys()

    @property
    def frequency_updates(self) -> bool:
        """Whether the controller takes a new frequency during a sine dwell's hold (the map names
        the registers of :data:`OPTIONAL` ``frequency_update``)."""
        return OPTIONAL["frequency_update"] <= self.holding.keys()

    @property
    def sweep_notches(self) -> bool:
        """Whether the controller lowers a sweep's amplitude over a notch (the map names the
        registers of :data:`OPTIONAL` ``sweep_notch``)."""
        return OPTIONAL["sweep_notch"] <= self.holding.keys()

    @property
    def drive_files(self) -> bool:
        """Whether the controller takes a drive file over the map's registers and plays it (the map
        names the registers of :data:`OPTIONAL` ``drive_file``)."""
        return OPTIONAL["drive_file"] <= self.holding.keys()

    def encode(self, register: Register, value: float | Iterable[float]) -> list[int]:
        """The 16-bit register values for ``value`` (a block: ``register.count`` values), in the
        map's word order (of each value)."""
        if register.count > 1:
            values = list(value)  # type: ignore[arg-type]
            if len(values) != register.count:
                raise ValueError(f"{register.name}: expected {register.count} values, got {len(values)}")
            one = Register(register.table, register.name, register.address, register.type)
            return [word for v in values for word in self.encode(one, v)]
        fmt = _STRUCT[register.type]
        try:
            raw = struct.pack(">" + fmt, int(value) if fmt != "f" else float(value))
        except struct.error as exc:
            raise ValueError(f"{register.name}: {value!r} does not fit a {register.type}") from exc
        words = [int.from_bytes(raw[i : i + 2], "big") for i in range(0, len(raw), 2)]
        return words if self.word_order == "big" else words[::-1]

    def decode(self, register: Register, words: Iterable[int]) -> float | int | tuple[float | int, ...]:
        """The value held in ``words`` (exactly ``register.width`` registers; a block's values as a
        tuple)."""
        words = list(words)
        if len(words) != register.width:
            raise ValueError(f"{register.name}: expected {register.width} registers, got {len(words)}")
        if register.count > 1:
            one = Register(register.table, register.name, register.address, register.type)
            step = TYPE_WIDTH[register.type]
            return tuple(self.decode(one, words[i : i + step]) for i in range(0, len(words), step))
        if self.word_order == "little":
            words = words[::-1]
        raw = b"".join(int(w).to_bytes(2, "big") for w in words)
        return struct.unpack(">" + _STRUCT[register.type], raw)[0]

    def encode_many(self, table: str, values: Mapping[str, float]) -> list[tuple[int, list[int]]]:
        """Encode named values into runs of consecutive registers: ``[(start_address, words), ...]``.

        Gaps between registers split the runs, so each run is one multi-register write.
        """
        regs = sorted((self.table(table)[name] for name in values), key=lambda r: r.address)
        runs: list[tuple[int, list[int]]] = []
        for reg in regs:
            words = self.encode(reg, values[reg.name])
            if runs and runs[-1][0] + len(runs[-1][1]) == reg.address:
                runs[-1][1].extend(words)
            else:
                runs.append((reg.address, words))
        return runs

    def span(self, table: str) -> tuple[int, int]:
        """``(first_address, count)`` covering every register of ``table``."""
        regs = self.table(table).values()
        first = min(r.address for r in regs)
        return first, max(r.address + r.width for r in regs) - first

    def runs(self, table: str) -> list[tuple[int, int]]:
        """``[(first_address, count), ...]``: the runs of consecutive registers of ``table``, split
        at the gaps (the controller refuses a request that touches an address the map leaves out) and
        at most :data:`MAX_READ_QUANTITY` registers long (one read request each)."""
        runs: list[tuple[int, int]] = []
        for reg in sorted(self.table(table).values(), key=lambda r: r.address):
            if runs and sum(runs[-1]) == reg.address and runs[-1][1] + reg.width <= MAX_READ_QUANTITY:
                runs[-1] = (runs[-1][0], runs[-1][1] + reg.width)
            else:
                runs.append((reg.address, reg.width))
        return runs

    def decode_span(self, table: str, first: int, words: list[int]) -> dict[str, float | int]:
        """Decode every register of ``table`` contained in ``words`` read from ``first``."""
        out: dict[str, float | int] = {}
        for reg in self.table(table).values():
            lo = reg.address - first
            if lo >= 0 and lo + reg.width <= len(words):
                out[reg.name] = self.decode(reg, words[lo : lo + reg.width])
        return out


def default_map_path() -> Path:
    """The register map shipped with the package."""
    return Path(str(resources.files("drivers") / "register_map.toml"))


def load_register_map(path: str | Path | None = None) -> RegisterMap:
    """Load and validate a register map; errors name the file and the key."""
    path = Path(path) if path is not None else default_map_path()
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise RegisterMapError(f"{path}: cannot read register map: {exc}") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RegisterMapError(f"{path}: not valid TOML: {exc}") from exc
    except RecursionError:  # tomllib recurses per level of nesting
        raise RegisterMapError(f"{path}: nested too deep: arrays or tables hundreds of levels deep") from None
    return parse_register_map(data, source=str(path))


def _fail(source: str, key: str, message: str) -> RegisterMapError:
    return RegisterMapError(f"{source}: [{key}] {message}")


def _parse_header(data: dict, source: str) -> tuple[str, int, str, int]:
    header = data.get("map")
    if not isinstance(header, dict):
        raise _fail(source, "map", "missing table (name, protocol_version, word_order, device_id)")
    unknown = set(header) - {"name", "protocol_version", "word_order", "device_id"}
    if unknown:
        raise _fail(source, "map", f"unknown keys {sorted(unknown)}")
    version = header.get("protocol_version")
    if not isinstance(version, int) or isinstance(version, bool) or not 0 <= version <= 0xFFFF:
        raise _fail(source, "map.protocol_version", f"must be an integer 0..65535, got {version!r}")
    order = header.get("word_order", "big")
    if order not in WORD_ORDERS:
        raise _fail(source, "map.word_order", f"must be one of {list(WORD_ORDERS)}, got {order!r}")
    device_id = header.get("device_id", 1)
    if not isinstance(device_id, int) or isinstance(device_id, bool) or not 1 <= device_id <= 247:
        raise _fail(source, "map.device_id", f"must be an integer 1..247, got {device_id!r}")
    return str(header.get("name", "")), version, order, device_id


def _parse_register(table: str, name: str, entry: object, source: str) -> Register:
    key = f"{table}.{name}"
    if not isinstance(entry, dict):
        raise _fail(source, key, "must be a table with address and type")
    unknown = set(entry) - _REGISTER_KEYS
    if unknown:
        raise _fail(source, key, f"unknown keys {sorted(unknown)}; allowed {sorted(_REGISTER_KEYS)}")
    address, rtype = entry.get("address"), entry.get("type")
    if not isinstance(address, int) or isinstance(address, bool) or not 0 <= address <= 0xFFFF:
        raise _fail(source, f"{key}.address", f"must be an integer 0..65535, got {address!r}")
    if rtype not in TYPE_WIDTH:
        raise _fail(source, f"{key}.type", f"unknown type {rtype!r}; use one of {sorted(TYPE_WIDTH)}")
    count = entry.get("count", 1)
    expected = BLOCKS.get(name, 1)
    if count != expected or isinstance(count, bool):
        what = f"a block of {expected} values" if expected > 1 else "one value (no count)"
        raise _fail(source, f"{key}.count", f"must be {expected} ({name} is {what}), got {count!r}")
    if address + TYPE_WIDTH[rtype] * count > 0x10000:
        raise _fail(source, f"{key}.address", "register runs past address 65535")
    doc, unit = str(entry.get("doc", "")), str(entry.get("unit", ""))
    return Register(table, name, address, rtype, unit, doc, count)


def _check_overlaps(table: str, regs: dict[str, Register], source: str) -> None:
    ordered = sorted(regs.values(), key=lambda r: r.address)
    for prev, cur in itertools.pairwise(ordered):
        if cur.address < prev.address + prev.width:
            raise _fail(
                source,
                f"{table}.{cur.name}",
                f"address {cur.address} overlaps {table}.{prev.name} "
                f"(addresses {prev.address}..{prev.address + prev.width - 1})",
            )


def parse_register_map(data: dict, source: str = "<built-in>") -> RegisterMap:
    """Validate a register map given as parsed TOML (a dict)."""
    unknown = set(data) - {"map", *TABLES}
    if unknown:
        raise _fail(source, ", ".join(sorted(unknown)), f"unknown tables; allowed: map, {', '.join(TABLES)}")
    name, version, order, device_id = _parse_header(data, source)
    tables: dict[str, dict[str, Register]] = {}
    for table in TABLES:
        raw = data.get(table, {})
        if not isinstance(raw, dict):
            raise _fail(source, table, "must be a table of registers")
        regs = {reg_name: _parse_register(table, reg_name, entry, source) for reg_name, entry in raw.items()}
        missing = REQUIRED[table] - set(regs)
        if missing:
            raise _fail(source, table, f"missing required registers {sorted(missing)}")
        _check_overlaps(table, regs, source)
        tables[table] = regs
    for capability, names in OPTIONAL.items():
        present = names & tables["holding"].keys()
        others = set().union(*(other for name, other in OPTIONAL.items() if name != capability))
        if present - others and present != names:  # a register of its own named, not all of them
            raise _fail(
                source,
                "holding",
                f"{capability} needs all of {sorted(names)}: the map names only {sorted(present)}",
            )
        inputs = OPTIONAL_INPUTS.get(capability, frozenset())
        if present == names and not inputs <= tables["input"].keys():
            missing = sorted(inputs - tables["input"].keys())
            raise _fail(source, "input", f"{capability} needs the input registers {missing} too")
    return RegisterMap(name, version, order, device_id, tables["holding"], tables["input"], source)
