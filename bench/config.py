"""The bench configuration: devices, limits, calibration, masses and aux channels, from TOML.

One file describes one bench (format in ``docs/configuration.md``). Nothing configured means the
simulated shaker bench: ``load_bench_config(None)``. Every key is checked when the file is read,
and every problem found is reported together in one :class:`ConfigError` naming the file and the
key, so a bad configuration never reaches a device. The configuration gives the sequences their
:class:`~sequences.limits.BenchLimits`, the one limit envelope the validation, the dry run, the
actuator client and the interlocks all check against.
"""

from __future__ import annotations

import itertools
import math
import numbers
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from bench.engine.channels import FrameChannels
from bench.engine.timing import EngineTiming
from bench.models.parameters import WfsSensor
from drivers.errors import RegisterMapError
from drivers.register_map import RegisterMap, load_register_map
from drivers.wfs_frame import FRAME_SIZE
from sequences.channels import (
    AUX_ROLES,
    DEFAULT_AUX_INPUTS,
    ENGINE_ROLES,
    AuxInput,
    Channel,
    ChannelSet,
    Role,
    role_of_standard_name,
)
from sequences.errors import problems_text
from sequences.limits import INTERLOCKS_ABOVE, BenchLimits
from sequences.metadata import check_metadata
from sequences.ranges import range_problem
from sequences.response_limits import (
    GRADED_INTERLOCKS,
    LIMITED_ROLES,
    LimitAction,
    LimitProfile,
    ResponseLimit,
)
from sequences.runs import RigKind
from sequences.toml_text import load_toml, toml_error_where, toml_table, toml_value

BENCH_KINDS = tuple(rig.value for rig in RigKind)
ACTUATOR_TRANSPORTS = ("simulated", "tcp", "rtu")
WFS_TRANSPORTS = ("simulated", "serial")
TARE_POLICIES = ("before_each_run", "once", "never")
TYRE_MODELS = (1, 2, 3)
#: What each role the engine needs is needed for, as a refusal says it.
_ROLE_NEEDS = {
    Role.BENCH_DISPLACEMENT: "the amplitude control and the displacement interlock",
    Role.PLATE_FORCE: "the force interlock and the contact force",
}
#: Bits on the serial line per byte (8N1: start, 8 data, stop): a frame rate must fit the baud rate.
_BITS_PER_BYTE = 10


class ConfigError(ValueError):
    """A bench configuration is refused; ``problems`` lists every ``file: key: reason`` found."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = tuple(problems)
        super().__init__(problems_text(problems))


@dataclass(frozen=True)
class ActuatorConfig:
    """How to reach the actuator controller: ``transport`` "simulated" (in-process, TCP on
    127.0.0.1), "tcp" (``host``:``port``) or "rtu" (``device`` at ``baudrate``, 8N1)."""

    transport: str = "simulated"
    host: str = "127.0.0.1"
    port: int = 502
    device: str = ""
    baudrate: int = 115200
    unit_id: int = 1
    register_map: Path | None = None  # None: the map shipped with the drivers
    timeout_s: float = 0.3
    read_attempts: int = 3
    heartbeat_period_s: float = 0.1
    watchdog_ms: int = 1500

    def load_register_map(self) -> RegisterMap:
        return load_register_map(self.register_map)


@dataclass(frozen=True)
class WfsConfig:
    """How to reach the WFS acquisition: "simulated" (a pseudo-terminal) or "serial" ``device``."""

    transport: str = "simulated"
    device: str = ""
    baudrate: int = 921600
    rate_hz: int = 1000


@dataclass(frozen=True)
class Calibration:
    """The 6x6 calibration/crosstalk matrix of the raw channels and when to tare."""

    matrix: tuple[tuple[float, ...], ...] = tuple(
        tuple(1.0 if i == j else 0.0 for j in range(6)) for i in range(6)
    )
    tare: str = "before_each_run"

    def matrix_array(self) -> np.ndarray:
        return np.array(self.matrix, dtype=float)


@dataclass(frozen=True)
class Masses:
    """Weighed masses: the wheel below the sensing element and the sensor; the bench plate's
    nominal mass above its load cell (the free run identifies the real one)."""

    wheel_below_sensor_kg: float = 29.0
    sensor_kg: float = 3.82
    plate_kg: float = 12.0


@dataclass(frozen=True)
class SensorStatement:
    """The WFS as the lab states it (its data sheet, or a hammer test of an earlier campaign): the
    bare sensor's eigenfrequency (Hz) and damping ratio. ``None``: not stated; the analysis then
    assumes :class:`~bench.models.parameters.WfsSensor`'s defaults (2200 Hz, 0.02) and says so. A
    hammer run of the campaign measures the sensor and overrides both."""

    eigenfrequency_hz: float | None = None
    damping_ratio: float | None = None

    @property
    def stated(self) -> bool:
        """Whether the configuration states anything of the sensor."""
        return self.eigenfrequency_hz is not None or self.damping_ratio is not None


@dataclass(frozen=True)
class Specimen:
    """What stands on the bench, for the dry run's model and the simulated world: the tyre model
    (the paper's 1, 2 or 3), whether the tyre is non-linear, whether the four-post car's damper is
    (``damper_nonlinear``: digressive, :class:`~bench.models.parameters.DamperNonlinearity`), the
    state before the first prompt (pressure, wheel fitted) and the static load the WFS carries at
    rest on the shaker (the tyre preload, N; on the four-post bench the model's weight above the
    sensor)."""

    tyre_model: int = 2
    nonlinear: bool = True
    damper_nonlinear: bool = False
    tyre_pressure_bar: float = 2.5
    wheel_fitted: bool = True
    preload_n: float = 0.0


@dataclass(frozen=True)
class Simulation:
    """The simulated devices: noise seed, whether they run paced in real time, whether in a
    process of their own (``own_process``; None: when paced, as hardware keeps its own time; an
    unpaced bench waits for its host anyway), and whether the paced WFS link has hardware flow
    control (``flow_control``: a host that stops reading holds the device back, which keeps up to
    ``wfs_hold_s`` of frames, instead of overrunning the port's 4095-byte buffer). The unpaced link
    always waits for its host, up to ``wfs_hold_s`` too (None: 1 s paced, 5 s unpaced)."""

    seed: int = 1
    paced: bool = False
    own_process: bool | None = None
    flow_control: bool = False
    wfs_hold_s: float | None = None

    @property
    def in_own_process(self) -> bool:
        """Whether the simulated devices run in a process of their own."""
        return self.paced if self.own_process is None else self.own_process


@dataclass(frozen=True)
class AmplitudeConfig:
    """How the engine brings a dwell's amplitude to its target (docs/engine.md, *Amplitude control*):
    within the dwell by amplitude updates the controller takes while running (``hold_within_dwell``;
    only where the controller's register map has them), to ``update_tolerance`` with at most
    ``max_updates`` per attempt, each ramped over ``ramp_s``; and after it, a point whose amplitude
    is beyond ``tolerance`` repeated at most ``max_repeats`` times.

    The bounds on what a command may do: a window's measurement is decided on only when at most
    ``max_missing_fraction`` of its frames were lost and it holds ``min_cycles`` cycles of frames
    (else the same command is measured again); one correction or update scales the command by at
    most ``max_step_factor``; a command exceeds its target by at most ``command_margin`` (beyond,
    the point ends flagged); a measured amplitude beyond its target by ``excursion_tolerance`` is
    the limit "amplitude excursion", acted on with ``excursion_action``."""

    hold_within_dwell: bool = True
    update_tolerance: float = 0.005
    max_updates: int = 3
    ramp_s: float = 0.1
    tolerance: float = 0.02
    max_repeats: int = 3
    max_missing_fraction: float = 0.05
    min_cycles: float = 1.0
    max_step_factor: float = 1.15
    command_margin: float = 0.25
    excursion_tolerance: float = 0.1
    excursion_action: LimitAction = LimitAction.INDICATE


@dataclass(frozen=True)
class InterlockActions:
    """The action of each of the bench's own interlocks a lab may grade (``[actions]``): the stroke,
    the plate force and the WFS overload; "interlock" unless configured."""

    displacement_limit: LimitAction = LimitAction.INTERLOCK
    force_limit: LimitAction = LimitAction.INTERLOCK
    wfs_overload: LimitAction = LimitAction.INTERLOCK


@dataclass(frozen=True)
class BenchConfig:
    """A whole bench configuration; ``source`` is its file (or ``<default>``)."""

    kind: RigKind = RigKind.SHAKER
    actuator: ActuatorConfig = field(default_factory=ActuatorConfig)
    wfs: WfsConfig = field(default_factory=WfsConfig)
    limits: BenchLimits = field(default_factory=BenchLimits)
    calibration: Calibration = field(default_factory=Calibration)
    masses: Masses = field(default_factory=Masses)
    sensor: SensorStatement = field(default_factory=SensorStatement)
    aux: tuple[AuxInput, ...] = DEFAULT_AUX_INPUTS
    specimen: Specimen = field(default_factory=Specimen)
    simulation: Simulation = field(default_factory=Simulation)
    timing: EngineTiming = field(default_factory=EngineTiming)
    #: the ``[metadata]`` table: the test metadata this bench states (bench, sensor, ...), only the
    #: fields the file gives (:mod:`sequences.metadata`; a sequence's and ``--meta`` win over it)
    metadata: Mapping[str, str] = field(default_factory=dict)
    amplitude: AmplitudeConfig = field(default_factory=AmplitudeConfig)
    actions: InterlockActions = field(default_factory=InterlockActions)
    response_limits: tuple[ResponseLimit, ...] = ()
    source: str = "<default>"

    @property
    def channels(self) -> ChannelSet:
        """The channels a run on this bench records, each with its role."""
        return FrameChannels(self.aux).recorded

    @property
    def wfs_sensor(self) -> WfsSensor:
        """The sensor as this configuration states it (``[sensor]``, its mass from ``[masses]``), what
        it does not state from :class:`WfsSensor`'s defaults (the paper's sensor: 2200 Hz, 0.02)."""
        stated, default = self.sensor, WfsSensor()
        return WfsSensor(
            mass_kg=self.masses.sensor_kg,
            eigenfrequency_hz=stated.eigenfrequency_hz or default.eigenfrequency_hz,
            damping_ratio=default.damping_ratio if stated.damping_ratio is None else stated.damping_ratio,
        )

    @property
    def simulated(self) -> bool:
        """True when any device is simulated (the simulated world is then needed)."""
        return "simulated" in (self.actuator.transport, self.wfs.transport)

    def to_toml(self) -> str:
        """The configuration as a file :func:`parse_bench_config` reads back to an equal one (for the
        record of a run)."""
        actuator = {f.name: getattr(self.actuator, f.name) for f in fields(ActuatorConfig)}
        actuator["register_map"] = str(actuator["register_map"]) if self.actuator.register_map else None
        limits = {name: getattr(self.limits, name) for name in BenchLimits.__slots__}
        tables = [
            [f"kind = {toml_value(self.kind)}"],
            toml_table("[actuator]", actuator),
            toml_table("[wfs]", _as_dict(self.wfs)),
            toml_table("[limits]", limits),
            toml_table("[calibration]", _as_dict(self.calibration)),
            toml_table("[masses]", _as_dict(self.masses)),
            toml_table("[sensor]", _as_dict(self.sensor)),
            toml_table("[aux]", {f"aux{i}": _aux_entry(a) for i, a in enumerate(self.aux)}),
            toml_table("[specimen]", _as_dict(self.specimen)),
            toml_table("[simulation]", _as_dict(self.simulation)),
            toml_table("[timing]", _as_dict(self.timing)),
            toml_table("[metadata]", self.metadata),
            toml_table("[amplitude]", _as_dict(self.amplitude)),
            toml_table("[actions]", {k: str(v) for k, v in _as_dict(self.actions).items()}),
            *(toml_table(f"[response_limits.{r.name}]", _limit_entry(r)) for r in self.response_limits),
        ]
        return "\n\n".join("\n".join(t) for t in tables) + "\n"


def measured_bench(config: BenchConfig) -> dict[str, object]:
    """What of ``config`` shapes a measurement, flat by dotted key (``limits.stroke_mm``): everything
    but how the devices are reached (the ``[actuator]`` table, the WFS's transport, device and baud
    rate), whether the simulated bench is paced, the engine's timeouts, the test metadata (a resume
    checks the sensor and tyre it names against the campaign's: docs/hdf5.md) and the file's name;
    ``simulated`` says whether the devices are simulated. Two configurations with equal values
    measure alike (a resume compares them)."""
    data = tomllib.loads(config.to_toml())
    del data["actuator"], data["simulation"]["paced"], data["timing"], data["metadata"]
    data["simulation"].pop("own_process", None)
    data["simulation"].pop("flow_control", None)
    data["simulation"].pop("wfs_hold_s", None)
    for key in ("transport", "device", "baudrate"):
        del data["wfs"][key]
    flat: dict[str, object] = {"simulated": config.simulated}

    def add(prefix: str, value: object) -> None:
        if isinstance(value, dict):
            for key, inner in value.items():
                add(f"{prefix}.{key}" if prefix else key, inner)
        else:
            flat[prefix] = value

    add("", data)
    return flat


def _as_dict(value: object) -> dict[str, object]:
    return {f.name: getattr(value, f.name) for f in fields(value)}


def _limit_entry(limit: ResponseLimit) -> dict[str, object]:
    """A response limit as its ``[response_limits.NAME]`` table."""
    return {
        "role": limit.role.value,
        "freqs_hz": list(limit.alarm.freqs_hz),
        "alarm": list(limit.alarm.levels),
        "abort": list(limit.abort.levels),
        "alarm_action": str(limit.alarm_action),
        "abort_action": str(limit.abort_action),
        "notch": limit.notch,
    }


def _aux_entry(aux: AuxInput) -> dict[str, object]:
    """An aux input as its ``[aux.auxN]`` table."""
    c = aux.channel
    return {
        "name": c.name,
        "unit": c.unit,
        "scale": aux.scale,
        "role": c.role.value,
        "description": c.description,
    }


#: Per kind, the limits, masses and specimen of the simulated benches where they differ from the
#: defaults.
KIND_DEFAULTS: dict[RigKind, dict[str, object]] = {
    RigKind.SHAKER: {},
    RigKind.FOUR_POST: {
        "limits": BenchLimits(
            stroke_mm=40.0,
            velocity_mm_s=1000.0,
            acceleration_m_s2=300.0,
            force_n=20_000.0,
            max_freq_hz=50.0,
            displacement_interlock_mm=45.0,
            force_interlock_n=25_000.0,
        ),
        "masses": Masses(plate_kg=15.0),
        # the car's damper digressive, as a car's is: a drive iteration needs a level-dependent rig
        "specimen": Specimen(damper_nonlinear=True),
    },
}


def default_bench_config(kind: str = RigKind.SHAKER) -> BenchConfig:
    """The simulated bench of ``kind`` (a :class:`~sequences.runs.RigKind` or its word) with every default."""
    rig = RigKind(kind)
    return BenchConfig(kind=rig, **KIND_DEFAULTS[rig])


def load_bench_config(path: str | Path | None) -> BenchConfig:
    """The configuration in ``path``, or the simulated shaker bench when ``path`` is None."""
    if path is None:
        return default_bench_config()
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError([f"{path}: cannot read the bench configuration: {exc.strerror or exc}"]) from exc
    except UnicodeDecodeError as exc:
        raise ConfigError([f"{path}: not UTF-8 text: {exc.reason} at byte {exc.start}"]) from exc
    return parse_bench_config(text, str(path), base_dir=path.parent)


def parse_bench_config(text: str, source: str, base_dir: Path | None = None) -> BenchConfig:
    """Check and build a configuration from TOML ``text``; relative paths are taken from ``base_dir``."""
    try:
        data = load_toml(text)
    except tomllib.TOMLDecodeError as exc:
        key, reason = toml_error_where(text, str(exc))
        raise ConfigError([f"{source}: {key + ': ' if key else ''}{reason}"]) from None
    if not data:
        raise ConfigError([f"{source}: empty file: a bench configuration needs at least kind"])
    return _Reader(source, base_dir or Path.cwd()).config(data)


class _Reader:
    """Reads the tables of a configuration, collecting ``file: key: reason`` problems."""

    def __init__(self, source: str, base_dir: Path) -> None:
        self.source, self.base_dir = source, base_dir
        self.problems: list[str] = []

    def add(self, key: str, message: str) -> None:
        self.problems.append(f"{self.source}: {key}: {message}")

    # ------------------------------------------------------------------ values
    def table(self, data: dict, key: str, allowed: tuple[str, ...]) -> dict:
        table = data.get(key, {})
        if not isinstance(table, dict):
            self.add(key, f"must be a table, got {table!r}")
            return {}
        for name in table:
            if name not in allowed:
                self.add(f"{key}.{name}", f"unknown key; allowed: {', '.join(allowed)}")
        return table

    def number(
        self,
        table: dict,
        key: str,
        name: str,
        default: float,
        *,
        lo: float | None = None,
        hi: float | None = None,
        lo_open: bool = False,
        integer: bool = False,
    ) -> float:
        full = f"{key}.{name}" if key else name
        return self.check(
            full, table.get(name, default), default, lo=lo, hi=hi, lo_open=lo_open, integer=integer
        )

    def check(
        self,
        full: str,
        value: object,
        default: float,
        *,
        lo: float | None = None,
        hi: float | None = None,
        lo_open: bool = False,
        integer: bool = False,
    ) -> float:
        """``value`` if it is a finite number in range, else ``default`` with the problem added."""
        name = full.rsplit(".", maxsplit=1)[-1]
        kind = "an integer" if integer else "a number"
        if (
            isinstance(value, bool)
            or not isinstance(value, numbers.Real)
            or (integer and not isinstance(value, numbers.Integral))
        ):
            self.add(full, f"expected {kind}, got {value!r} ({type(value).__name__})")
            return default
        if not math.isfinite(value):
            self.add(full, f"{value!r} is not a finite number")
            return default
        problem = range_problem(value, name, lo, hi, lo_open=lo_open)
        if problem is not None:
            self.add(full, problem)
            return default
        return int(value) if integer else float(value)

    def text(self, table: dict, key: str, name: str, default: str, choices: tuple = ()) -> str:
        value = table.get(name, default)
        if not isinstance(value, str):
            self.add(f"{key}.{name}" if key else name, f"expected a string, got {value!r}")
            return default
        if choices and value not in choices:
            self.add(f"{key}.{name}" if key else name, f"{value!r} is not one of {list(choices)}")
            return default
        return value

    def boolean(self, table: dict, key: str, name: str, default: bool) -> bool:
        value = table.get(name, default)
        if not isinstance(value, bool):
            self.add(f"{key}.{name}", f"expected true or false, got {value!r}")
            return default
        return value

    # ------------------------------------------------------------------ tables
    def config(self, data: dict) -> BenchConfig:
        top = (
            "kind",
            "actuator",
            "wfs",
            "limits",
            "calibration",
            "masses",
            "sensor",
            "aux",
            "specimen",
            "simulation",
            "timing",
            "metadata",
            "amplitude",
            "actions",
            "response_limits",
        )
        for name in data:
            if name not in top:
                self.add(name, f"unknown key; allowed: {', '.join(top)}")
        kind = self.text(data, "", "kind", RigKind.SHAKER, BENCH_KINDS)
        base = default_bench_config(kind)
        actuator, wfs = self.actuator(data), self.wfs(data)
        limits = self.limits(data, base)
        config = BenchConfig(
            kind=RigKind(kind),
            actuator=actuator,
            wfs=wfs,
            limits=limits,
            calibration=self.calibration(data),
            masses=self.masses(data, base.masses),
            sensor=self.sensor(data),
            aux=self.aux(data),
            specimen=self.specimen(data, base.specimen),
            simulation=self.simulation(data),
            timing=self.timing(data),
            metadata=self.metadata(data),
            amplitude=self.amplitude(data, limits),
            actions=self.actions(data),
            response_limits=self.response_limits(data),
            source=self.source,
        )
        for limit in config.response_limits:
            if not config.channels.bound(limit.role):
                self.add(
                    f"response_limits.{limit.name}.role",
                    f"no recorded channel plays {limit.role.value} (bind it in [aux])",
                )
        if self.problems:
            raise ConfigError(self.problems)
        return config

    def actuator(self, data: dict) -> ActuatorConfig:
        d = ActuatorConfig()
        t = self.table(data, "actuator", tuple(f.name for f in fields(ActuatorConfig)))
        transport = self.text(t, "actuator", "transport", d.transport, ACTUATOR_TRANSPORTS)
        device = self.text(t, "actuator", "device", d.device)
        if transport == "rtu" and not device:
            self.add("actuator.device", "transport 'rtu' needs the serial device, e.g. /dev/ttyUSB0")
        register_map = None
        if "register_map" in t:
            path = Path(self.text(t, "actuator", "register_map", ""))
            register_map = path if path.is_absolute() else self.base_dir / path
            try:
                load_register_map(register_map)
            except RegisterMapError as exc:
                self.add("actuator.register_map", str(exc))
        config = ActuatorConfig(
            transport=transport,
            host=self.text(t, "actuator", "host", d.host),
            port=self.number(t, "actuator", "port", d.port, lo=1, hi=65535, integer=True),
            device=device,
            baudrate=self.number(t, "actuator", "baudrate", d.baudrate, lo=0, lo_open=True, integer=True),
            unit_id=self.number(t, "actuator", "unit_id", d.unit_id, lo=1, hi=247, integer=True),
            register_map=register_map,
            timeout_s=self.number(t, "actuator", "timeout_s", d.timeout_s, lo=0, lo_open=True),
            read_attempts=self.number(
                t, "actuator", "read_attempts", d.read_attempts, lo=1, hi=10, integer=True
            ),
            heartbeat_period_s=self.number(
                t, "actuator", "heartbeat_period_s", d.heartbeat_period_s, lo=0, lo_open=True
            ),
            watchdog_ms=self.number(
                t, "actuator", "watchdog_ms", d.watchdog_ms, lo=1, hi=65535, integer=True
            ),
        )
        longest_ms = 1000 * (config.timeout_s * config.read_attempts + config.heartbeat_period_s)
        if config.watchdog_ms <= longest_ms:
            self.add(
                "actuator.watchdog_ms",
                f"{config.watchdog_ms} ms would trip on one slow reply: a request can hold the link for "
                f"timeout_s x read_attempts + heartbeat_period_s = {longest_ms:.0f} ms "
                f"(allowed > {longest_ms:.0f})",
            )
        return config

    def wfs(self, data: dict) -> WfsConfig:
        d = WfsConfig()
        t = self.table(data, "wfs", tuple(f.name for f in fields(WfsConfig)))
        transport = self.text(t, "wfs", "transport", d.transport, WFS_TRANSPORTS)
        device = self.text(t, "wfs", "device", d.device)
        if transport == "serial" and not device:
            self.add("wfs.device", "transport 'serial' needs the serial device, e.g. /dev/ttyUSB1")
        baudrate = self.number(t, "wfs", "baudrate", d.baudrate, lo=0, lo_open=True, integer=True)
        line_max_hz = baudrate // (FRAME_SIZE * _BITS_PER_BYTE)
        rate_hz = self.number(t, "wfs", "rate_hz", d.rate_hz, lo=100, hi=max(100, line_max_hz), integer=True)
        return WfsConfig(transport, device, baudrate, rate_hz)

    def limits(self, data: dict, base: BenchConfig) -> BenchLimits:
        """The ``[limits]`` table: every :class:`BenchLimits` field, positive; the frequency range in
        order; the controller's interlock thresholds above the host's stroke and force limits."""
        t = self.table(data, "limits", BenchLimits.__slots__)
        values = {
            name: self.number(t, "limits", name, getattr(base.limits, name), lo=0, lo_open=True)
            for name in BenchLimits.__slots__
        }
        if values["min_freq_hz"] >= values["max_freq_hz"]:
            self.add("limits.max_freq_hz", f"{values['max_freq_hz']:g} Hz is not above min_freq_hz")
            values["max_freq_hz"] = values["min_freq_hz"] * 2
        for interlock, limit in INTERLOCKS_ABOVE:
            values[interlock] = self.check(
                f"limits.{interlock}", values[interlock], values[limit] * 1.5, lo=values[limit], lo_open=True
            )
        return BenchLimits(**values)

    def calibration(self, data: dict) -> Calibration:
        d = Calibration()
        t = self.table(data, "calibration", ("matrix", "tare"))
        tare = self.text(t, "calibration", "tare", d.tare, TARE_POLICIES)
        raw = t.get("matrix", d.matrix)
        if not isinstance(raw, list | tuple) or len(raw) != 6:
            rows = len(raw) if isinstance(raw, list | tuple) else type(raw).__name__
            self.add("calibration.matrix", f"must be 6x6 (6 rows of 6 numbers), got {rows} rows")
            return Calibration(tare=tare)
        matrix = []
        for i, row in enumerate(raw):
            if not isinstance(row, list | tuple) or len(row) != 6:
                self.add(f"calibration.matrix[{i}]", f"must be a row of 6 numbers, got {row!r}")
                return Calibration(tare=tare)
            matrix.append(
                tuple(self.check(f"calibration.matrix[{i}][{j}]", v, 0.0) for j, v in enumerate(row))
            )
        if np.linalg.matrix_rank(np.array(matrix)) < 6:
            self.add("calibration.matrix", "is singular: the six loads cannot be told apart")
        return Calibration(tuple(matrix), tare)

    def masses(self, data: dict, base: Masses) -> Masses:
        t = self.table(data, "masses", tuple(f.name for f in fields(Masses)))
        return Masses(
            **{
                f.name: self.number(t, "masses", f.name, getattr(base, f.name), lo=0, lo_open=True)
                for f in fields(Masses)
            }
        )

    def sensor(self, data: dict) -> SensorStatement:
        """The ``[sensor]`` table: the eigenfrequency above 0 Hz, the damping ratio from 0 to 1 (an
        underdamped sensor rings); each may be left out (not stated)."""
        t = self.table(data, "sensor", tuple(f.name for f in fields(SensorStatement)))
        limits = {"eigenfrequency_hz": {"lo": 0, "lo_open": True}, "damping_ratio": {"lo": 0, "hi": 1}}
        return SensorStatement(
            **{
                name: self.number(t, "sensor", name, math.nan, **bounds) if name in t else None
                for name, bounds in limits.items()
            }
        )

    def aux(self, data: dict) -> tuple[AuxInput, ...]:
        """The aux inputs: each one's recorded name, unit, scale, role (by default the simulated
        bench's wiring) and description. The roles the engine needs must each be played by one
        input, and no input may take another role's standard name."""
        names = tuple(f"aux{i}" for i in range(len(DEFAULT_AUX_INPUTS)))
        t = self.table(data, "aux", names)
        inputs = []
        for name, default in zip(names, DEFAULT_AUX_INPUTS, strict=True):
            entry = self.table(t, name, ("name", "unit", "scale", "role", "description")) if name in t else {}
            key, d = f"aux.{name}", default.channel
            roles = tuple(r.value for r in AUX_ROLES)
            channel = Channel(
                self.text(entry, key, "name", d.name),
                self.text(entry, key, "unit", d.unit),
                self.text(entry, key, "description", d.description),
                role=Role(self.text(entry, key, "role", d.role.value, roles)),
            )
            if not re.fullmatch(r"[a-z][a-z0-9_]*", channel.name):
                self.add(f"{key}.name", f"{channel.name!r} must be lower case letters, digits and _")
            taken = role_of_standard_name(channel.name)
            if taken not in (None, channel.role):
                self.add(
                    f"{key}.name",
                    f"{channel.name!r} is the standard name of the {taken.value} role: give this input"
                    f" role = {taken.value!r} or another name",
                )
            inputs.append(AuxInput(channel, self.number(entry, key, "scale", default.scale)))
        seen = [a.channel.name for a in inputs]
        for i, c in enumerate(seen):
            if seen.index(c) < i:
                self.add(f"aux.{names[i]}.name", f"{c!r} is already the name of {names[seen.index(c)]}")
        for role in AUX_ROLES:
            players = [n for n, a in zip(names, inputs, strict=True) if a.channel.role is role]
            if role is not Role.SPARE and len(players) > 1:
                self.add(f"aux.{players[1]}.role", f"{role.value} is already the role of {players[0]}")
        for role in ENGINE_ROLES:
            if not any(a.channel.role is role for a in inputs):
                self.add(
                    "aux",
                    f"no input has the role {role.value}, which every run needs ({_ROLE_NEEDS[role]}):"
                    f" set role = {role.value!r} in the [aux.auxN] table of the input that carries it",
                )
        return tuple(inputs)

    def specimen(self, data: dict, d: Specimen) -> Specimen:
        t = self.table(data, "specimen", tuple(f.name for f in fields(Specimen)))
        model = self.number(t, "specimen", "tyre_model", d.tyre_model, lo=1, hi=3, integer=True)
        return Specimen(
            tyre_model=model,
            nonlinear=self.boolean(t, "specimen", "nonlinear", d.nonlinear),
            damper_nonlinear=self.boolean(t, "specimen", "damper_nonlinear", d.damper_nonlinear),
            tyre_pressure_bar=self.number(
                t, "specimen", "tyre_pressure_bar", d.tyre_pressure_bar, lo=0.5, hi=5.0
            ),
            wheel_fitted=self.boolean(t, "specimen", "wheel_fitted", d.wheel_fitted),
            preload_n=self.number(t, "specimen", "preload_n", d.preload_n, lo=0),
        )

    def timing(self, data: dict) -> EngineTiming:
        """The ``[timing]`` table: every engine timeout and period, positive (docs/configuration.md)."""
        t = self.table(data, "timing", tuple(f.name for f in fields(EngineTiming)))
        d = EngineTiming()
        return EngineTiming(
            **{
                f.name: self.number(t, "timing", f.name, getattr(d, f.name), lo=0, lo_open=True)
                for f in fields(EngineTiming)
            }
        )

    def metadata(self, data: dict) -> dict[str, str]:
        """The ``[metadata]`` table: texts by the names of :data:`~sequences.metadata.METADATA_FIELDS`
        (the calibration date ``YYYY-MM-DD``); each may be left out."""
        given, problems = check_metadata(data.get("metadata", {}))
        for key, reason in problems:
            self.add(key, reason)
        return given

    def amplitude(self, data: dict, limits: BenchLimits) -> AmplitudeConfig:
        """The ``[amplitude]`` table: tolerances within (0, 0.5), the update's below the repeat's
        (an update must leave room for the noise); counts 0..10; the ramp no shorter than the
        shortest taper and at most 10 s."""
        d = AmplitudeConfig()
        t = self.table(data, "amplitude", tuple(f.name for f in fields(AmplitudeConfig)))
        config = AmplitudeConfig(
            hold_within_dwell=self.boolean(t, "amplitude", "hold_within_dwell", d.hold_within_dwell),
            update_tolerance=self.number(
                t, "amplitude", "update_tolerance", d.update_tolerance, lo=0, hi=0.5, lo_open=True
            ),
            max_updates=self.number(t, "amplitude", "max_updates", d.max_updates, lo=0, hi=10, integer=True),
            ramp_s=self.number(t, "amplitude", "ramp_s", d.ramp_s, lo=limits.min_taper_s, hi=10.0),
            tolerance=self.number(t, "amplitude", "tolerance", d.tolerance, lo=0, hi=0.5, lo_open=True),
            max_repeats=self.number(t, "amplitude", "max_repeats", d.max_repeats, lo=0, hi=10, integer=True),
            max_missing_fraction=self.number(
                t, "amplitude", "max_missing_fraction", d.max_missing_fraction, lo=0, hi=0.5
            ),
            min_cycles=self.number(t, "amplitude", "min_cycles", d.min_cycles, lo=0.5, hi=100.0),
            max_step_factor=self.number(
                t, "amplitude", "max_step_factor", d.max_step_factor, lo=1.0, hi=1.5, lo_open=True
            ),
            command_margin=self.number(t, "amplitude", "command_margin", d.command_margin, lo=0, hi=1.0),
            excursion_tolerance=self.number(
                t, "amplitude", "excursion_tolerance", d.excursion_tolerance, lo=0, hi=1.0, lo_open=True
            ),
            excursion_action=LimitAction(
                self.text(
                    t,
                    "amplitude",
                    "excursion_action",
                    str(d.excursion_action),
                    tuple(str(a) for a in LimitAction),
                )
            ),
        )
        if config.update_tolerance > config.tolerance:
            self.add(
                "amplitude.update_tolerance",
                f"{config.update_tolerance:g} is above the tolerance {config.tolerance:g} of a repeat"
                " (allowed <= tolerance)",
            )
        return config

    def actions(self, data: dict) -> InterlockActions:
        """The ``[actions]`` table: an action of :class:`LimitAction` per graded interlock."""
        t = self.table(data, "actions", GRADED_INTERLOCKS)
        d = InterlockActions()
        choices = tuple(str(a) for a in LimitAction)
        return InterlockActions(
            **{
                name: LimitAction(self.text(t, "actions", name, str(getattr(d, name)), choices))
                for name in GRADED_INTERLOCKS
            }
        )

    def response_limits(self, data: dict) -> tuple[ResponseLimit, ...]:
        """The ``[response_limits.NAME]`` tables: a role to watch, ascending ``freqs_hz`` and at each
        an ``alarm`` level below the ``abort`` level (both positive), their actions and ``notch``."""
        tables = data.get("response_limits", {})
        if not isinstance(tables, dict):
            self.add("response_limits", f"must be a table of limits, got {tables!r}")
            return ()
        limits = []
        keys = ("role", "freqs_hz", "alarm", "abort", "alarm_action", "abort_action", "notch")
        for name, entry in tables.items():
            key = f"response_limits.{name}"
            if not isinstance(entry, dict):
                self.add(key, f"must be a table ({', '.join(keys)}), got {entry!r}")
                continue
            t = self.table(tables, name, keys)
            problems = len(self.problems)
            roles = tuple(str(r) for r in LIMITED_ROLES)
            role = self.text(t, key, "role", "", roles)
            if "role" not in t:
                self.add(f"{key}.role", f"missing: one of {list(roles)}")
            freqs = self._levels(t, key, "freqs_hz")
            alarm, abort = self._levels(t, key, "alarm"), self._levels(t, key, "abort")
            choices = tuple(str(a) for a in LimitAction)
            alarm_action = self.text(t, key, "alarm_action", str(LimitAction.INDICATE), choices)
            abort_action = self.text(t, key, "abort_action", str(LimitAction.INTERLOCK), choices)
            notch = self.boolean(t, key, "notch", True)
            if len(self.problems) > problems:
                continue
            if any(b <= a for a, b in itertools.pairwise(freqs)):
                self.add(f"{key}.freqs_hz", f"{list(freqs)} must ascend")
            if not len(freqs) == len(alarm) == len(abort):
                lengths = f"{len(freqs)}, {len(alarm)}, {len(abort)}"
                self.add(key, f"freqs_hz, alarm and abort must be as long: {lengths}")
            elif below := [f for f, a, b in zip(freqs, alarm, abort, strict=True) if not a < b]:
                self.add(f"{key}.alarm", f"must lie below abort at every frequency; not at {below} Hz")
            if len(self.problems) > problems:
                continue
            limits.append(
                ResponseLimit(
                    str(name),
                    Role(role),
                    LimitProfile(freqs, alarm),
                    LimitProfile(freqs, abort),
                    LimitAction(alarm_action),
                    LimitAction(abort_action),
                    notch,
                )
            )
        return tuple(limits)

    def _levels(self, table: dict, key: str, name: str) -> tuple[float, ...]:
        """A non-empty list of positive finite numbers at ``key.name``."""
        value = table.get(name)
        ok = isinstance(value, list) and bool(value)
        ok = ok and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) and v > 0
            for v in value
        )
        if not ok:
            self.add(f"{key}.{name}", f"expected a non-empty list of positive numbers, got {value!r}")
            return ()
        return tuple(float(v) for v in value)

    def simulation(self, data: dict) -> Simulation:
        d = Simulation()
        t = self.table(data, "simulation", ("seed", "paced", "own_process", "flow_control", "wfs_hold_s"))
        return Simulation(
            seed=self.number(t, "simulation", "seed", d.seed, lo=0, hi=2**32 - 1, integer=True),
            paced=self.boolean(t, "simulation", "paced", d.paced),
            own_process=self.boolean(t, "simulation", "own_process", False) if "own_process" in t else None,
            flow_control=self.boolean(t, "simulation", "flow_control", d.flow_control),
            wfs_hold_s=(
                self.number(t, "simulation", "wfs_hold_s", 1.0, lo=0.01, hi=60.0)
                if "wfs_hold_s" in t
                else None
            ),
        )
