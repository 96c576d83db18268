"""Validation of a sequence against the bench's limits, before anything moves.

One code path for sequence files and for sequences built in Python: the loader checks the file's
structure (keys, tables, types of text fields) and hands the steps it could build to
:func:`check_steps`; :func:`validate` runs the same checks on a :class:`Sequence`. Every problem
names the key as in a sequence file (``steps[3].amplitude_mm``, ``steps[2].freqs_hz[4]``; steps
count from 0, in file order) and the allowed range.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterable

from sequences.channels import ChannelSet, Role
from sequences.errors import Problem, SequenceError
from sequences.limits import DRIVE_RATE_RANGE_HZ, BenchLimits, peak_acceleration_m_s2, peak_velocity_mm_s
from sequences.ranges import fmt_number as _fmt
from sequences.ranges import range_problem
from sequences.steps import (
    ANSWER_TYPES,
    GRID_ORDERS,
    HYDRAULIC_LEVELS,
    IDENTIFICATION_SHAPES,
    ITERATION_RESPONSES,
    PROMPT_ACTIONS,
    ROAD_CLASSES,
    SWEEP_LAWS,
    AdaptiveDwell,
    DriveIteration,
    DwellGrid,
    FreeRun,
    HammerTest,
    HydraulicLevel,
    Hydraulics,
    MeanPosition,
    Prompt,
    PromptAction,
    RoadReplay,
    Sequence,
    SineDwell,
    Step,
    Sweep,
    Tare,
    TrackedDwell,
    crossover_amplitude_mm,
)

#: Relative slack on the kinematic limits: a crossover amplitude computed from a limit must pass
#: the same limit despite the last bit of floating-point rounding.
_RELATIVE_SLACK = 1e-9
_LIMITED_BY = (None, "velocity", "acceleration", "force")
_DWELL_TIMING = (
    "settle_cycles",
    "settle_min_s",
    "measure_cycles",
    "measure_min_s",
    "taper_in_s",
    "taper_out_s",
)


def validate(sequence: Sequence, limits: BenchLimits, channels: ChannelSet | None = None) -> None:
    """Raise :class:`SequenceError` with every problem of ``sequence`` under ``limits`` and, given
    the bench's recorded ``channels``, every channel a step needs that the bench does not record."""
    problems = check_sequence_header(sequence.name, sequence.description, sequence.source)
    if not isinstance(sequence.steps, tuple | list) or not sequence.steps:
        problems.append(Problem(sequence.source, "steps", "a sequence needs at least one step"))
    else:
        problems += check_steps(enumerate(sequence.steps), limits, sequence.source)
        if channels is not None:
            problems += check_channels(enumerate(sequence.steps), channels, sequence.source)
    if problems:
        raise SequenceError.of(problems)


#: Roles the analysis of a run with the wheel needs beyond those every run needs: the four-post
#: sweep's hub-acceleration compensation and m_wheel. (A shaker's dwells need none: its hub is
#: clamped, and their analysis without a hub accelerometer takes it as not moving.)
_ANALYSIS_ROLES = {
    Sweep: (Role.HUB_ACCELERATION,),
    RoadReplay: (Role.HUB_ACCELERATION,),
    DriveIteration: (Role.PLATE_FORCE,),
}
#: Speeds of a generated road (km/h).
ROAD_SPEED_RANGE_KM_H = (1.0, 250.0)


def check_channels(steps: Iterable[tuple[int, Step]], channels: ChannelSet, source: str) -> list[Problem]:
    """The channels the ``(index, step)`` pairs name or need that a bench recording ``channels``
    lacks: an adaptive grid's ``output`` and ``input`` (a recorded name, or a role's standard name
    such as ``f_plate_n`` for the bench's plate-force channel), and the roles the analysis of each
    run needs."""
    problems = []
    for index, step in steps:
        key = f"steps[{index}]"
        adaptive = getattr(step, "adaptive", None)
        named = {}
        if isinstance(adaptive, AdaptiveDwell):
            named = {f"{key}.adaptive.{name}": getattr(adaptive, name) for name in ("output", "input")}
        elif isinstance(step, TrackedDwell):
            named = {f"{key}.{name}": getattr(step, name) for name in ("output", "input")}
        for where, channel in named.items():
            if isinstance(channel, str) and channels.resolve(channel) is None:
                problems.append(
                    Problem(
                        source,
                        where,
                        f"the bench records no channel {channel!r} (it records {', '.join(channels.names)})",
                    )
                )
        for role in _ANALYSIS_ROLES.get(type(step), ()):
            if not channels.bound(role):
                problems.append(
                    Problem(
                        source,
                        key,
                        f"its analysis needs a channel with the role {role.value}, and no channel of the"
                        f" bench has it (the bench configuration's [aux.auxN] role)",
                    )
                )
    return problems


def check_sequence_header(name: object, description: object, source: str) -> list[Problem]:
    problems = []
    if not isinstance(name, str) or not name.strip():
        problems.append(Problem(source, "sequence.name", f"must be a non-empty string, got {name!r}"))
    if not isinstance(description, str):
        problems.append(Problem(source, "sequence.description", f"must be a string, got {description!r}"))
    return problems


def check_steps(steps: Iterable[tuple[int, Step]], limits: BenchLimits, source: str) -> list[Problem]:
    """The problems of ``(index, step)`` pairs; prompt ids must be unique across them."""
    problems: list[Problem] = []
    prompt_ids: dict[str, int] = {}
    # a sequence brings the hydraulics up itself: they are off before its first step
    hydraulics = HydraulicLevel.OFF
    for index, step in steps:
        check = _Checker(source, f"steps[{index}]", limits)
        if type(step) in _STEP_CHECKS:
            _STEP_CHECKS[type(step)](check, step)
        elif isinstance(step, Prompt):
            check.prompt(step)
            if isinstance(step.id, str) and step.id in prompt_ids:
                check.add("id", f"prompt id {step.id!r} is already used by steps[{prompt_ids[step.id]}]")
            elif isinstance(step.id, str):
                prompt_ids[step.id] = index
        elif isinstance(step, Hydraulics):
            hydraulics = check.hydraulics(step.level, hydraulics)
        elif not isinstance(step, Tare):
            check.add("", f"{step!r} is not a step")
        problems += check.problems
    return problems


class _Checker:
    """Collects the problems of one step; keys are relative to the step (``prefix``)."""

    def __init__(self, source: str, prefix: str, limits: BenchLimits) -> None:
        self.source, self.prefix, self.limits = source, prefix, limits
        self.problems: list[Problem] = []

    def add(self, key: str, message: str) -> None:
        full = f"{self.prefix}.{key}" if key else self.prefix
        self.problems.append(Problem(self.source, full, message))

    def hydraulics(self, level: object, before: str) -> str:
        """Check a hydraulics step given the level ``before`` it; the level after it."""
        self.one_of("level", level, HYDRAULIC_LEVELS)
        if level == HydraulicLevel.HIGH and before == HydraulicLevel.OFF:
            self.add(
                "level",
                "'high' while the hydraulics are off: the controller raises the pressure to high only from"
                ' low; allowed here: off, low (put a hydraulics step with level = "low" before it)',
            )
        return level if level in HYDRAULIC_LEVELS else before

    # ---------------------------------------------------------------- values
    def number(
        self,
        key: str,
        value: object,
        lo: float | None = None,
        hi: float | None = None,
        *,
        lo_open: bool = False,
        unit: str = "",
        lo_why: str = "",
        hi_why: str = "",
        integer: bool = False,
    ) -> float | None:
        """``value`` as a float if it is a finite number within the range, else None (problem added,
        worded by :func:`sequences.ranges.range_problem`; ``lo_why``/``hi_why`` name the bounds)."""
        kind = "an integer" if integer else "a number"
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            self.add(key, f"expected {kind}, got {value!r} ({type(value).__name__})")
            return None
        if integer and not isinstance(value, numbers.Integral):
            self.add(key, f"expected {kind}, got {value!r}")
            return None
        number = float(value)
        if not math.isfinite(number):
            self.add(key, f"{value!r} is not a finite number")
            return None
        name = re.sub(r"\[\d+\]$", "", key.rsplit(".", maxsplit=1)[-1])
        problem = range_problem(
            number, name, lo, hi, lo_open=lo_open, unit=unit, lo_why=lo_why, hi_why=hi_why
        )
        if problem is not None:
            self.add(key, problem)
            return None
        return number

    def optional_number(self, key: str, value: object, **kwargs) -> float | None:
        return None if value is None else self.number(key, value, **kwargs)

    def text(self, key: str, value: object, *, required: bool = True) -> None:
        if not isinstance(value, str) or (required and not value.strip()):
            self.add(key, f"expected {'a non-empty' if required else 'a'} string, got {value!r}")

    def one_of(self, key: str, value: object, allowed: Iterable[object]) -> bool:
        allowed = tuple(allowed)
        if value not in allowed:
            self.add(key, f"{value!r} is not one of {list(allowed)}")
            return False
        return True

    # ---------------------------------------------------------------- bench quantities
    def mean(self, mean_mm: object) -> float | None:
        stroke = self.limits.stroke_mm
        value = self.number("mean_mm", mean_mm, -stroke, stroke, lo_open=True, unit="mm", hi_why="the stroke")
        if value is not None and abs(value) >= stroke:
            self.add("mean_mm", f"{_fmt(value)} mm leaves no stroke (allowed |mean_mm| < {_fmt(stroke)} mm)")
            return None
        return value

    def frequency(self, key: str, freq_hz: object) -> float | None:
        lim = self.limits
        return self.number(
            key,
            freq_hz,
            lim.min_freq_hz,
            lim.max_freq_hz,
            unit="Hz",
            lo_why="the bench's lowest frequency",
            hi_why="the bench's highest frequency",
        )

    def amplitude(self, key: str, amplitude_mm: object, mean_mm: float | None) -> float | None:
        room = self.limits.stroke_mm - abs(mean_mm or 0.0)
        why = f"the {_fmt(self.limits.stroke_mm)} mm stroke"
        if mean_mm:
            why += f" less |mean_mm| {_fmt(abs(mean_mm))}"
        return self.number(key, amplitude_mm, 0.0, room, lo_open=True, unit="mm", hi_why=why)

    def kinematics(self, key: str, freq_hz: float, amplitude_mm: float, remedy: str) -> None:
        """Peak velocity and acceleration of a sine at the bench's limits."""
        lim = self.limits
        velocity = peak_velocity_mm_s(freq_hz, amplitude_mm)
        if velocity > lim.velocity_mm_s * (1 + _RELATIVE_SLACK):
            allowed = lim.velocity_mm_s / (2 * math.pi * freq_hz)
            self.add(
                key,
                f"{_fmt(amplitude_mm)} mm at {_fmt(freq_hz)} Hz needs a peak velocity of "
                f"{velocity:.0f} mm/s, "
                f"beyond the bench's {_fmt(lim.velocity_mm_s)} mm/s (allowed amplitude <= {allowed:.4g} mm "
                f"at {_fmt(freq_hz)} Hz{remedy})",
            )
        acceleration = peak_acceleration_m_s2(freq_hz, amplitude_mm)
        if acceleration > lim.acceleration_m_s2 * (1 + _RELATIVE_SLACK):
            allowed = lim.acceleration_m_s2 * 1e3 / (2 * math.pi * freq_hz) ** 2
            self.add(
                key,
                f"{_fmt(amplitude_mm)} mm at {_fmt(freq_hz)} Hz needs a peak acceleration of "
                f"{acceleration:.0f} m/s^2, beyond the bench's {_fmt(lim.acceleration_m_s2)} m/s^2 "
                f"(allowed amplitude <= {allowed:.4g} mm at {_fmt(freq_hz)} Hz{remedy})",
            )

    def tapers(self, taper_in_s: object, taper_out_s: object) -> tuple[float | None, float | None]:
        lo = self.limits.min_taper_s
        why = "the controller's shortest taper"
        return (
            self.number("taper_in_s", taper_in_s, lo, unit="s", lo_why=why),
            self.number("taper_out_s", taper_out_s, lo, unit="s", lo_why=why),
        )

    def dwell_timing(self, step: SineDwell | DwellGrid) -> bool:
        ok = [
            self.number(name, getattr(step, name), 0.0, unit=unit) is not None
            for name, unit in (
                ("settle_cycles", ""),
                ("settle_min_s", "s"),
                ("measure_cycles", ""),
                ("measure_min_s", "s"),
            )
        ]
        ok += [t is not None for t in self.tapers(step.taper_in_s, step.taper_out_s)]
        if all(ok) and step.measure_cycles == 0 and step.measure_min_s == 0:
            self.add("measure_min_s", "nothing to measure: measure_cycles and measure_min_s are both 0")
            return False
        return all(ok)

    def dwell_length(self, key: str, dwell: SineDwell) -> None:
        if dwell.duration_s > self.limits.max_step_s:
            self.add(
                key,
                f"a dwell of {dwell.duration_s:.6g} s at {_fmt(dwell.freq_hz)} Hz is beyond the controller's "
                f"longest setpoint (allowed <= {_fmt(self.limits.max_step_s)} s)",
            )

    # ---------------------------------------------------------------- steps
    def dwell(self, step: SineDwell) -> None:
        mean = self.mean(step.mean_mm)
        freq = self.frequency("freq_hz", step.freq_hz)
        amplitude = self.amplitude("amplitude_mm", step.amplitude_mm, mean)
        timing_ok = self.dwell_timing(step)
        self.optional_number(
            "requested_amplitude_mm", step.requested_amplitude_mm, lo=0.0, lo_open=True, unit="mm"
        )
        self.one_of("amplitude_limited_by", step.amplitude_limited_by, _LIMITED_BY)
        if freq is not None and amplitude is not None:
            self.kinematics("amplitude_mm", freq, amplitude, "")
            if timing_ok:
                self.dwell_length("freq_hz", step)

    def grid(self, grid: DwellGrid) -> None:
        mean = self.mean(grid.mean_mm)
        freqs = self._list("freqs_hz", grid.freqs_hz, self.frequency)
        amplitudes = self._list(
            "amplitudes_mm", grid.amplitudes_mm, lambda key, a: self.amplitude(key, a, mean)
        )
        for k, f in enumerate(freqs or ()):
            first = freqs.index(f)
            if f is not None and first < k:
                self.add(f"freqs_hz[{k}]", f"{_fmt(f)} Hz is already in the grid at freqs_hz[{first}]")
        self.one_of("order", grid.order, GRID_ORDERS)
        v_max = self.optional_number(
            "max_velocity_mm_s", grid.max_velocity_mm_s, lo=0.0, lo_open=True, unit="mm/s"
        )
        a_max = self.optional_number(
            "max_acceleration_m_s2", grid.max_acceleration_m_s2, lo=0.0, lo_open=True, unit="m/s^2"
        )
        timing_ok = self.dwell_timing(grid)
        self.text("label", grid.label, required=False)
        maxima_ok = (v_max is not None or grid.max_velocity_mm_s is None) and (
            a_max is not None or grid.max_acceleration_m_s2 is None
        )
        if freqs and amplitudes and maxima_ok:
            self._grid_points(grid, freqs, amplitudes, (v_max, a_max), timing_ok)
        if grid.adaptive is not None:
            self.adaptive(grid.adaptive)
            if grid.order != "amplitude-major":
                self.add("order", "an adaptive grid refines one amplitude at a time: use amplitude-major")

    def free_run(self, step: FreeRun) -> None:
        self.grid(step.grid)
        if step.grid.adaptive is not None:
            self.add("adaptive", "a free_run step has no adaptive table; only a dwell_grid has")

    def adaptive(self, a: AdaptiveDwell) -> None:
        """The ``adaptive`` table: channel names, targets, lengths and the point budget."""
        if not isinstance(a, AdaptiveDwell):
            self.add("adaptive", f"expected an adaptive table, got {a!r}")
            return
        self.text("adaptive.output", a.output)
        self.text("adaptive.input", a.input)
        self.number("adaptive.plate_mass_kg", a.plate_mass_kg, 0.0, unit="kg")
        self.number("adaptive.settle_tolerance", a.settle_tolerance, 0.0, 0.5, lo_open=True)
        self.number(
            "adaptive.magnitude_target_pct", a.magnitude_target_pct, 0.0, 100.0, lo_open=True, unit="%"
        )
        self.number("adaptive.phase_target_deg", a.phase_target_deg, 0.0, 90.0, lo_open=True, unit="deg")
        self.number(
            "adaptive.min_hold_cycles", a.min_hold_cycles, 2.0, lo_why="the settling test's two windows"
        )
        low = self.number("adaptive.min_hold_s", a.min_hold_s, 0.0, unit="s")
        self.number(
            "adaptive.max_hold_s",
            a.max_hold_s,
            0.0 if low is None else low,
            self.limits.max_step_s,
            lo_open=low is None,
            unit="s",
            lo_why="min_hold_s" if low is not None else "",
            hi_why="the controller's longest setpoint",
        )
        self.number("adaptive.interpolation_db", a.interpolation_db, 0.0, lo_open=True, unit="dB")
        self.number("adaptive.interpolation_deg", a.interpolation_deg, 0.0, lo_open=True, unit="deg")
        self.number("adaptive.max_added_points", a.max_added_points, 0, integer=True)
        self.number("adaptive.min_spacing_hz", a.min_spacing_hz, 0.0, lo_open=True, unit="Hz")

    def _grid_points(
        self,
        grid: DwellGrid,
        freqs: list[float | None],
        amplitudes: list[float | None],
        maxima: tuple[float | None, float | None],
        timing_ok: bool,
    ) -> None:
        """Each valid (frequency, amplitude) point at the amplitude the crossover gives it."""
        v_max, a_max = maxima
        remedy = "; or lower the grid's max_velocity_mm_s / max_acceleration_m_s2"
        if v_max is None and a_max is None:
            remedy = "; or set the grid's max_velocity_mm_s / max_acceleration_m_s2"
        valid_freqs = [(k, f) for k, f in enumerate(freqs) if f is not None]
        for j, nominal_mm in enumerate(amplitudes):
            if nominal_mm is None:
                continue
            for _, f in valid_freqs:
                used_mm, _ = crossover_amplitude_mm(f, nominal_mm, v_max, a_max)
                self.kinematics(f"amplitudes_mm[{j}]", f, used_mm, remedy)
        if timing_ok and valid_freqs:
            k, lowest = min(valid_freqs, key=lambda kf: kf[1])
            timing = {name: getattr(grid, name) for name in _DWELL_TIMING}
            self.dwell_length(f"freqs_hz[{k}]", SineDwell(lowest, 1.0, **timing))

    def _list(self, key: str, values: object, check) -> list[float | None] | None:
        if not isinstance(values, tuple | list):
            self.add(key, f"expected a list of numbers, got {values!r}")
            return None
        if not values:
            self.add(key, "the grid has no values: give at least one")
            return None
        return [check(f"{key}[{k}]", v) for k, v in enumerate(values)]

    def sweep(self, step: Sweep) -> None:
        mean = self.mean(step.mean_mm)
        start = self.frequency("start_hz", step.start_hz)
        end = self.frequency("end_hz", step.end_hz)
        if start is not None and start == end:
            self.add("end_hz", f"a sweep needs end_hz != start_hz (both {_fmt(start)} Hz)")
        amplitude = self.amplitude("amplitude_mm", step.amplitude_mm, mean)
        self.one_of("law", step.law, SWEEP_LAWS)
        taper_in, taper_out = self.tapers(step.taper_in_s, step.taper_out_s)
        duration = self.number(
            "duration_s",
            step.duration_s,
            0.0,
            self.limits.max_step_s,
            lo_open=True,
            unit="s",
            hi_why="the controller's longest setpoint",
        )
        if None not in (duration, taper_in, taper_out) and taper_in + taper_out >= duration:
            self.add(
                "duration_s",
                f"{_fmt(duration)} s leaves no sweep after the tapers "
                f"(allowed duration_s > taper_in_s + taper_out_s = {_fmt(taper_in + taper_out)} s)",
            )
        self.text("label", step.label, required=False)
        if None not in (start, end, amplitude):
            remedy = "; a sweep is checked at its highest frequency"
            self.kinematics("amplitude_mm", max(start, end), amplitude, remedy)

    def tracked(self, step: TrackedDwell) -> None:
        """A tracked dwell: its search band within the bench's frequencies (start below end), at
        least 3 search points, the amplitude within the stroke and the kinematic limits at the
        band's top (the track may move past it by ``freq_band_pct``), the track's length within
        one setpoint's, the update period and the stop bands positive."""
        mean = self.mean(step.mean_mm)
        start = self.frequency("search_start_hz", step.search_start_hz)
        end = self.frequency("search_end_hz", step.search_end_hz)
        if None not in (start, end) and not start < end:
            self.add("search_end_hz", f"{_fmt(end)} Hz must lie above search_start_hz {_fmt(start)} Hz")
        amplitude = self.amplitude("amplitude_mm", step.amplitude_mm, mean)
        self.number("search_points", step.search_points, 3, 50, integer=True, unit="points")
        self.text("output", step.output)
        self.text("input", step.input)
        self.number("plate_mass_kg", step.plate_mass_kg, 0.0, 1000.0, unit="kg")
        self.tapers(step.taper_in_s, step.taper_out_s)
        longest = "the controller's longest setpoint"
        track = self.number(
            "track_s", step.track_s, 0.0, self.limits.max_step_s, lo_open=True, unit="s", hi_why=longest
        )
        self.optional_number("track_cycles", step.track_cycles, lo=1.0, hi=1e6, unit="cycles")
        update = self.number("update_s", step.update_s, 0.05, 10.0, unit="s")
        band = self.number("freq_band_pct", step.freq_band_pct, 0.0, 50.0, lo_open=True, unit="%")
        self.number("ratio_band_pct", step.ratio_band_pct, 0.0, 1000.0, lo_open=True, unit="%")
        self.text("label", step.label, required=False)
        if None not in (start, end, amplitude, band):
            top = min(end * (1 + band / 100), self.limits.max_freq_hz)  # where the track may go
            remedy = "; a tracked dwell is checked where its band may take it"
            self.kinematics("amplitude_mm", top, amplitude, remedy)
        if None not in (update, track) and update > track:
            self.add("update_s", f"{_fmt(update)} s is longer than the track ({_fmt(track)} s)")

    def replay(self, step: RoadReplay) -> None:
        """A road replay: exactly one source (a drive file, or a road class with its speed and
        length), the generated road's values in range, the tapers and the cut within the
        controller's limits. The drive's values against the bench's limits are the dry run's."""
        self.mean(step.mean_mm)
        taper_in, taper_out = self.tapers(step.taper_in_s, step.taper_out_s)
        self.text("label", step.label, required=False)
        for key in ("file", "channel", "time_column", "road_class"):
            self.text(key, getattr(step, key), required=False)
        longest = "the controller's longest setpoint"
        duration = self.number(
            "duration_s", step.duration_s, 0.0, self.limits.max_step_s, unit="s", hi_why=longest
        )
        if not isinstance(step.file, str) or not isinstance(step.road_class, str):
            return
        if bool(step.file) == bool(step.road_class):
            self.add(
                "file" if step.file else "road_class",
                "a road replay plays a drive file (file) or a generated road (road_class, speed_km_h,"
                " duration_s): this one gives " + ("both" if step.file else "neither"),
            )
            return
        if step.file:
            for key in ("speed_km_h", "seed", "sample_rate_hz", "band_cycles_per_m"):
                if getattr(step, key) != getattr(_REPLAY_DEFAULTS, key):
                    self.add(key, "belongs to a generated road (road_class), not to a drive file")
        else:
            self._generated_road(step, duration)
        if None not in (duration, taper_in, taper_out) and duration and taper_in + taper_out >= duration:
            self.add(
                "duration_s",
                f"{_fmt(duration)} s leaves nothing between the tapers "
                f"(allowed duration_s > taper_in_s + taper_out_s = {_fmt(taper_in + taper_out)} s)",
            )

    def _generated_road(self, step: RoadReplay, duration: float | None) -> None:
        self.one_of("road_class", step.road_class, ROAD_CLASSES)
        self.number("speed_km_h", step.speed_km_h, *ROAD_SPEED_RANGE_KM_H, unit="km/h")
        self.number("seed", step.seed, 0, 2**63 - 1, integer=True)
        self.number("sample_rate_hz", step.sample_rate_hz, *DRIVE_RATE_RANGE_HZ, unit="Hz")
        if duration == 0:
            self.add("duration_s", "a generated road needs its length (allowed duration_s > 0 s)")
        band = step.band_cycles_per_m
        if not isinstance(band, tuple | list) or len(band) != 2:
            self.add("band_cycles_per_m", f"expected two numbers [lowest, highest], got {band!r}")
            return
        low = self.number("band_cycles_per_m[0]", band[0], 0.0, lo_open=True, unit="cycles/m")
        high = self.number("band_cycles_per_m[1]", band[1], 0.0, lo_open=True, unit="cycles/m")
        if None not in (low, high) and low >= high:
            self.add(
                "band_cycles_per_m", f"[{_fmt(low)}, {_fmt(high)}]: the lowest must lie below the highest"
            )

    def iteration(self, step: DriveIteration) -> None:
        """A drive iteration: its target named (its file's contents are the plan's to read), the
        response one of :data:`ITERATION_RESPONSES`, the band within the bench's frequencies, the
        identification's shape, level and length, the regularisation and the gain (below 1: a
        correction of a whole error overshoots wherever the rig responds more than identified), the
        stop rules and the S-N exponent in their ranges, the tapers and the cut within the
        controller's limits. The drives' values against the bench's limits are the dry run's, drive
        by drive."""
        lim = self.limits
        self.mean(step.mean_mm)
        taper_in, taper_out = self.tapers(step.taper_in_s, step.taper_out_s)
        self.text("target", step.target)
        for key in ("target_channel", "target_unit", "time_column", "label"):
            self.text(key, getattr(step, key), required=False)
        self.one_of("response", step.response, ITERATION_RESPONSES)
        self.one_of("identification", step.identification, IDENTIFICATION_SHAPES)
        longest = "the controller's longest setpoint"
        duration = self.number("duration_s", step.duration_s, 0.0, lim.max_step_s, unit="s", hi_why=longest)
        if None not in (duration, taper_in, taper_out) and duration and taper_in + taper_out >= duration:
            self.add(
                "duration_s",
                f"{_fmt(duration)} s leaves nothing between the tapers "
                f"(allowed duration_s > taper_in_s + taper_out_s = {_fmt(taper_in + taper_out)} s)",
            )
        band = self.band("band_hz", step.band_hz, lim.max_freq_hz)
        judged = self.band("error_band_hz", step.error_band_hz, lim.max_freq_hz)
        if band is not None and judged is not None and not band[0] <= judged[0] < judged[1] <= band[1]:
            self.add(
                "error_band_hz",
                f"[{_fmt(judged[0])}, {_fmt(judged[1])}] must lie inside band_hz"
                f" [{_fmt(band[0])}, {_fmt(band[1])}] (the error is judged where the drive is corrected)",
            )
        self.number("settle_s", step.settle_s, 0.0, 10.0, unit="s")
        stroke = "the bench's stroke"
        self.number(
            "identification_rms_mm",
            step.identification_rms_mm,
            0.0,
            lim.stroke_mm,
            lo_open=True,
            unit="mm",
            hi_why=stroke,
        )
        self.number(
            "identification_s",
            step.identification_s,
            8.0,
            lim.max_step_s,
            unit="s",
            lo_why="two FRF segments of 4 s",
            hi_why=longest,
        )
        self.number("identification_seed", step.identification_seed, 0, 2**63 - 1, integer=True)
        self.number("regularisation", step.regularisation, 0.0, 1.0, lo_open=True)
        self.number(
            "gain", step.gain, 0.0, 1.0, lo_open=True, unit="", hi_why="a correction below the whole error"
        )
        self.number("max_iterations", step.max_iterations, 1, 99, integer=True, unit="iterations")
        self.number("rms_error_pct", step.rms_error_pct, 0.0, 100.0, lo_open=True, unit="%")
        self.number("in_band_pct", step.in_band_pct, 0.0, 100.0, unit="%")
        self.number("sn_exponent", step.sn_exponent, 1.0, 20.0, unit="")
        self.number("max_drive_mm", step.max_drive_mm, 0.0, lim.stroke_mm, unit="mm", hi_why=stroke)

    def band(self, key: str, band: object, top_hz: float) -> tuple[float, float] | None:
        """A band ``[lowest, highest]`` in Hz within 0..``top_hz`` (the bench's), lowest below
        highest; None (problem added) otherwise."""
        if not isinstance(band, tuple | list) or len(band) != 2:
            self.add(key, f"expected two numbers [lowest, highest], got {band!r}")
            return None
        low = self.number(f"{key}[0]", band[0], 0.0, top_hz, unit="Hz", hi_why="the bench's")
        high = self.number(f"{key}[1]", band[1], 0.0, top_hz, unit="Hz", hi_why="the bench's")
        if low is None or high is None:
            return None
        if low >= high:
            self.add(key, f"[{_fmt(low)}, {_fmt(high)}]: the lowest must lie below the highest")
            return None
        return low, high

    def hammer(self, step: HammerTest) -> None:
        lim = self.limits
        self.number(
            "trigger_level_n",
            step.trigger_level_n,
            0.0,
            lim.wfs_force_n,
            lo_open=True,
            unit="N",
            hi_why="the WFS range",
        )
        capture = self.number(
            "capture_s",
            step.capture_s,
            0.0,
            lim.max_capture_s,
            lo_open=True,
            unit="s",
            hi_why="the acquisition's capture buffer",
        )
        pre = self.number("pre_trigger_s", step.pre_trigger_s, 0.0, unit="s")
        if capture is not None and pre is not None and pre >= capture:
            self.add(
                "pre_trigger_s",
                f"{_fmt(pre)} s leaves nothing after the trigger (allowed < capture_s = {_fmt(capture)} s)",
            )
        self.number("blows", step.blows, 1, 100, unit="", integer=True)

    def prompt(self, step: Prompt) -> None:
        self.text("id", step.id)
        self.text("text", step.text)
        answer_ok = self.one_of("answer", step.answer, ANSWER_TYPES)
        if step.unit is not None:
            self.text("unit", step.unit)
        lo = self.optional_number("minimum", step.minimum)
        hi = self.optional_number("maximum", step.maximum)
        if lo is not None and hi is not None and lo >= hi:
            self.add(
                "minimum",
                f"{_fmt(lo)} is not below maximum {_fmt(hi)} (allowed minimum < maximum)",
            )
            lo = hi = None
        choices = step.choices
        choices_ok = isinstance(choices, tuple | list) and all(isinstance(c, str) and c for c in choices)
        if not choices_ok:
            self.add("choices", f"expected a list of non-empty strings, got {choices!r}")
        if step.action is not None:
            self.one_of("action", step.action, PROMPT_ACTIONS)
        if answer_ok:
            self._prompt_answer(step, lo, hi, choices_ok)

    def _prompt_answer(self, step: Prompt, lo: float | None, hi: float | None, choices_ok: bool) -> None:
        """The answer type fits the action, the range/choices and the target."""
        answer_of_action = {PromptAction.SET_TYRE_PRESSURE: "number", PromptAction.SET_DAMPER: "choice"}
        needs = answer_of_action.get(step.action or "")
        if needs and step.answer != needs:
            self.add("answer", f"action {step.action!r} needs answer = {needs!r}, got {step.answer!r}")
        if step.answer == "choice" and choices_ok and len(step.choices) < 2:
            self.add("choices", "a choice needs at least two choices")
        if step.answer != "choice" and step.choices:
            self.add("choices", f"only answer = 'choice' takes choices (answer is {step.answer!r})")
        if step.answer != "number" and (step.minimum is not None or step.maximum is not None):
            self.add("minimum", f"only answer = 'number' takes minimum/maximum (answer is {step.answer!r})")
        if step.action == PromptAction.SET_TYRE_PRESSURE and step.target is None:
            self.add("target", "action 'set_tyre_pressure' needs the pressure asked for as target (bar)")
        if step.target is None:
            return
        if step.answer == "number":
            self.number(
                "target",
                step.target,
                lo,
                hi,
                unit=step.unit or "",
                lo_why="the prompt's minimum",
                hi_why="the prompt's maximum",
            )
        elif step.answer == "choice":
            self.one_of("target", step.target, step.choices if choices_ok else ())
        else:
            self.add("target", f"answer = {step.answer!r} takes no target")


_REPLAY_DEFAULTS = RoadReplay()

#: The check of each step type that needs only its own values (prompts and hydraulics need the
#: steps before them: :func:`check_steps` checks them itself).
_STEP_CHECKS = {
    SineDwell: _Checker.dwell,
    DwellGrid: _Checker.grid,
    FreeRun: _Checker.free_run,
    Sweep: _Checker.sweep,
    TrackedDwell: _Checker.tracked,
    RoadReplay: _Checker.replay,
    DriveIteration: _Checker.iteration,
    HammerTest: _Checker.hammer,
    MeanPosition: lambda check, step: check.mean(step.mean_mm),
}
