"""Running a sequence on a bench into a campaign file: the composition of everything.

:func:`plan_campaign` loads the bench configuration and the sequence, validates the sequence against
the bench's limits and dry-runs it on the bench model; nothing is opened before the plan stands.
:func:`run_campaign` then opens the devices (real ones, or the simulated lab when the configuration
names none), builds the engine, subscribes the recorder and the post-run analysis, and runs.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, replace
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from bench.app.actuator_thread import ThreadedActuator
from bench.app.answers import FileAnswers
from bench.app.post_run import CampaignKnowledge, PostRunAnalysis
from bench.app.progress import DoneBefore
from bench.app.recorder import Recorder
from bench.app.resume_check import check_resume
from bench.app.simulated import UNPACED_BACKLOG_S, SimulatedLab, SimulatedLabSettings, TargetAnswers
from bench.app.terminal import TerminalOperator
from bench.config import BenchConfig, load_bench_config
from bench.dry_run import dry_run
from bench.engine import events as ev
from bench.engine.amplitude import AmplitudeControl
from bench.engine.channels import FrameChannels
from bench.engine.contracts import Operator
from bench.engine.engine import Engine, EngineTiming, SyncBits, is_measurement
from bench.engine.interlocks import standard_interlocks
from bench.models.parameters import WfsSensor
from bench.store import CampaignWriter, open_campaign
from drivers.actuator import ActuatorClient
from drivers.errors import LinkError
from drivers.wfs_frame import Status
from drivers.wfs_reader import WfsReader
from drivers.wfs_transform import LoadProcessor
from sequences import DwellGrid, FreeRun, Sequence, SineDwell, dump_sequence, load_sequence, validate

#: The WFS's eigenfrequency assumed until a hammer test of this campaign measured it (the paper's
#: sensor rings at about 2.2 kHz).
DEFAULT_SENSOR_EIGENFREQUENCY_HZ = 2200.0


class PlanRefusedError(ValueError):
    """The dry run refused the sequence on this bench; nothing was opened or moved."""


def software_version() -> str:
    try:
        return version("wfs-bench")
    except PackageNotFoundError:
        return "unknown"


@dataclass(frozen=True)
class CampaignPlan:
    """A validated sequence on a configured bench, with the texts that produced them."""

    config: BenchConfig
    config_text: str
    sequence: Sequence
    sequence_text: str


def plan_campaign(
    sequence_path: Path, config_path: Path | None = None, *, realtime: bool = False
) -> CampaignPlan:
    """Load and check everything before anything is opened: SequenceError / ConfigError name the
    file and the key; PlanRefusedError lists every point the dry run refuses. ``realtime`` paces the
    simulated bench in real time (the configuration's ``simulation.paced``; no effect on hardware)."""
    config = load_bench_config(config_path)
    if realtime:
        config = replace(config, simulation=replace(config.simulation, paced=True))
    sequence = load_sequence(sequence_path, config.limits)
    config_text = Path(config_path).read_text() if config_path else config.to_toml()
    return plan_sequence(sequence, config, Path(sequence_path).read_text(), config_text)


def plan_sequence(
    sequence: Sequence, config: BenchConfig, sequence_text: str | None = None, config_text: str | None = None
) -> CampaignPlan:
    """Check a sequence built in Python (or loaded) against ``config``: the same validation as a
    sequence file gets, then the dry run. The texts recorded with the campaign default to the
    sequence and configuration written out as TOML."""
    validate(sequence, config.limits, config.channels)
    refusals = dry_run(sequence, config).refusals
    if refusals:
        raise PlanRefusedError("\n".join(str(r) for r in refusals))
    return CampaignPlan(
        config,
        config_text if config_text is not None else config.to_toml(),
        sequence,
        sequence_text if sequence_text is not None else dump_sequence(sequence),
    )


@dataclass
class BenchDevices:
    """The opened devices: the actuator, the acquisition, the person (or simulated operator)."""

    actuator: ThreadedActuator
    acquisition: WfsReader
    operator: Operator
    lab: SimulatedLab | None = None


@contextlib.contextmanager
def open_bench(
    config: BenchConfig,
    operator: Operator | None = None,
    answers: Mapping[str, float | str | bool] | None = None,
) -> Iterator[BenchDevices]:
    """Open the configured devices, or the simulated lab when the configuration names none.

    ``operator``: who answers prompts (default: the simulated operator on the simulated bench, the
    terminal on real hardware; the front ends pass their own). ``answers``: prompt answers checked
    beforehand (:func:`bench.app.answers.load_answers`), given instead of an operator: on the
    simulated bench they are applied to the simulated world."""
    if operator is not None and answers is not None:
        raise ValueError("give an operator or answers, not both")
    transports = {config.actuator.transport, config.wfs.transport}
    if "simulated" in transports and transports != {"simulated"}:
        raise ValueError(f"{config.source}: a simulated device cannot be mixed with real ones")
    with contextlib.ExitStack() as stack:
        lab = None
        if config.simulated:
            lab = stack.enter_context(
                SimulatedLab(
                    SimulatedLabSettings(
                        kind=config.kind,
                        paced=config.simulation.paced,
                        seed=config.simulation.seed,
                        tyre_pressure_bar=config.specimen.tyre_pressure_bar,
                        specimen_mounted=config.specimen.wheel_fitted,
                        tyre_model=config.specimen.tyre_model,
                        nonlinear=config.specimen.nonlinear,
                        aux_roles=tuple(a.channel.role for a in config.aux),
                    )
                )
            )
            host, port = lab.address
            wfs_url = lab.wfs_port
            if answers is not None:
                operator = FileAnswers(answers, lab.operator)
            operator = operator or TargetAnswers(lab.operator)
        else:
            host, port, wfs_url = config.actuator.host, config.actuator.port, config.wfs.device
            if answers is not None:
                operator = FileAnswers(answers)
        operator = operator or TerminalOperator()
        actuator = ThreadedActuator(lambda: _client(config, host, port))
        stack.callback(actuator.close)
        try:
            actuator.connect(config.actuator.heartbeat_period_s, config.actuator.watchdog_ms)
        except (LinkError, OSError) as exc:
            raise DeviceUnreachableError(config, "actuator", host, port, exc) from exc
        reader = WfsReader.serial(wfs_url, baudrate=config.wfs.baudrate)
        stack.enter_context(reader)
        if not reader.wait_connected(5.0):
            raise DeviceUnreachableError(config, "wfs", wfs_url, None, reader.last_error)
        reader.set_rate(config.wfs.rate_hz)
        yield BenchDevices(actuator, reader, operator, lab)


class DeviceUnreachableError(ConnectionError):
    """A device of the bench could not be opened: the message names the configuration file and the
    keys that say where the device is, the address tried and why it failed."""

    def __init__(self, config: BenchConfig, device: str, where: str, port: int | None, cause: object) -> None:
        if device == "wfs":
            keys, what = "wfs.device", f"the WFS acquisition at {where}"
        elif config.actuator.transport == "rtu":
            keys, what = "actuator.device", f"the actuator controller at {config.actuator.device}"
        else:
            keys, what = "actuator.host, actuator.port", f"the actuator controller at {where}:{port}"
        origin = f"{config.source}: {keys}: " if not config.simulated else ""
        super().__init__(f"{origin}cannot reach {what}: {cause}")


def _client(config: BenchConfig, host: str, port: int) -> ActuatorClient:
    a = config.actuator
    common = {
        "register_map": a.load_register_map(),
        "limits": config.soft_limits,
        "timeout_s": a.timeout_s,
        "read_attempts": a.read_attempts,
    }
    if a.transport == "rtu":
        return ActuatorClient.rtu(a.device, baudrate=a.baudrate, **common)
    return ActuatorClient.tcp(host, port, **common)


def build_engine(config: BenchConfig, devices: BenchDevices) -> Engine:
    """The engine on ``devices`` with the configured channels, interlocks and tare policy (and a
    short backlog on the unpaced simulated bench, which waits for the engine)."""
    unpaced = devices.lab is not None and not devices.lab.settings.paced
    channels = FrameChannels(config.aux, LoadProcessor(matrix=config.calibration.matrix_array()))
    return Engine(
        devices.actuator,
        devices.acquisition,
        devices.operator,
        channels=channels,
        interlocks=standard_interlocks(
            channels.recorded,
            displacement_limit_mm=config.limits.stroke_mm,
            force_limit_n=config.limits.force_n,
        ),
        sync_bits=SyncBits(int(Status.EXCITATION_ACTIVE), int(Status.AMPLITUDE_HOLD)),
        sample_rate_hz=float(config.wfs.rate_hz),
        amplitude_control=AmplitudeControl(max_command_mm=config.soft_limits.max_amplitude_mm),
        tare=config.calibration.tare,
        bench_kind=config.kind,
        timing=EngineTiming(backlog_s=UNPACED_BACKLOG_S) if unpaced else EngineTiming(),
    )


@dataclass(frozen=True)
class CampaignOutcome:
    """How the sequence ended, and what the analysis said after each run."""

    status: str
    reason: str
    analyses: list[ev.AnalysisDone]


class _ResumeFromFile:
    """The engine's resume plan, read from the campaign file being resumed."""

    def __init__(self, path: Path) -> None:
        with open_campaign(path) as campaign:
            self._runs = {
                run.run_id: (run.status, run.completed_point_indices(), run.n_samples)
                for run in campaign.runs
            }

    def run_complete(self, run_id: str) -> bool:
        return run_id in self._runs and self._runs[run_id][0] == "complete"

    def completed_points(self, run_id: str) -> set[int]:
        return set(self._runs[run_id][1]) if run_id in self._runs else set()

    def recorded_samples(self, run_id: str) -> int:
        return self._runs[run_id][2] if run_id in self._runs else 0


def run_campaign(
    plan: CampaignPlan,
    out_path: Path,
    *,
    resume: bool = False,
    operator: Operator | None = None,
    answers: Mapping[str, float | str | bool] | None = None,
    subscribers: tuple[Callable[[ev.Event], None], ...] = (),
    on_engine: Callable[[Engine], None] | None = None,
    knowledge: CampaignKnowledge | None = None,
) -> CampaignOutcome:
    """Run ``plan`` into the campaign file ``out_path``.

    A new file is created; an existing campaign file takes the sequence's runs beside its own (the
    four-post sequence after the shaker's), unless it holds runs of this very sequence: then only
    ``resume`` continues it, skipping its complete runs and points. ``on_engine`` receives the
    engine before it runs (a front end keeps it to request pause, abort and e-stop). ``answers``:
    the prompts' answers of an unattended run (see :func:`open_bench`). ``knowledge``:
    what the campaign established so far (sensor, plate masses, tyres), carried from one sequence to
    the next; by default it starts from the configuration and the runs already in the file."""
    out_path = Path(out_path)
    resume_plan = _check_target(plan, out_path, resume)
    with open_bench(plan.config, operator, answers) as devices:
        engine = build_engine(plan.config, devices)
        if on_engine is not None:
            on_engine(engine)
        return _run_on(
            engine, plan, out_path, resume_plan=resume_plan, subscribers=subscribers, knowledge=knowledge
        )


def run_on_engine(
    engine: Engine,
    plan: CampaignPlan,
    out_path: Path,
    *,
    resume: bool = False,
    subscribers: tuple[Callable[[ev.Event], None], ...] = (),
    knowledge: CampaignKnowledge | None = None,
) -> CampaignOutcome:
    """Like :func:`run_campaign`, on an engine whose bench stays open between sequences (a front
    end that shows and switches the bench between runs). The recorder, the analysis and
    ``subscribers`` are unsubscribed when the sequence ends."""
    out_path = Path(out_path)
    resume_plan = _check_target(plan, out_path, resume)
    return _run_on(
        engine, plan, out_path, resume_plan=resume_plan, subscribers=subscribers, knowledge=knowledge
    )


def _check_target(plan: CampaignPlan, out_path: Path, resume: bool) -> _ResumeFromFile | None:
    """Refuse a campaign file that cannot take the sequence (before anything is opened); the resume
    plan when resuming."""
    existing = _run_ids(out_path)
    if existing is None and resume:
        raise ValueError(f"{out_path}: no campaign file to resume")
    if existing and not resume and existing & _planned_runs(plan):
        raise ValueError(
            f"{out_path} holds runs of sequence {plan.sequence.name!r} already: resume it (--resume)"
            " or write to another file"
        )
    if not resume:
        return None
    with open_campaign(out_path) as campaign:
        check_resume(campaign, plan.sequence, plan.config)
    return _ResumeFromFile(out_path)


def held_runs(plan: CampaignPlan, out_path: Path) -> set[str]:
    """The runs of ``plan``'s sequence that the campaign file ``out_path`` holds already (none when
    there is no file; StoreError when the file is no campaign file): a new start into it must
    resume them."""
    return (_run_ids(Path(out_path)) or set()) & _planned_runs(plan)


def _planned_runs(plan: CampaignPlan) -> set[str]:
    return {
        Engine.run_id(plan.sequence, i) for i, step in enumerate(plan.sequence.steps) if is_measurement(step)
    }


def _run_on(
    engine: Engine,
    plan: CampaignPlan,
    out_path: Path,
    *,
    resume_plan: _ResumeFromFile | None,
    subscribers: tuple[Callable[[ev.Event], None], ...],
    knowledge: CampaignKnowledge | None,
) -> CampaignOutcome:
    analyses: list[ev.AnalysisDone] = []
    with _campaign_writer(plan, out_path, out_path.exists()) as campaign:
        knowledge = knowledge or initial_knowledge(plan.config)
        own = [
            Recorder(campaign),
            PostRunAnalysis(out_path, engine.bus.publish, knowledge),
            lambda e: analyses.append(e) if isinstance(e, ev.AnalysisDone) else None,
        ]
        engine.bus.subscribe(own[0], critical=True)
        for subscriber in (*own[1:], *subscribers):
            engine.bus.subscribe(subscriber)
        try:
            outcome = engine.run(
                plan.sequence,
                sequence_text=plan.sequence_text,
                config_text=plan.config_text,
                resume=resume_plan,
            )
        finally:
            for subscriber in (*own, *subscribers):
                engine.bus.unsubscribe(subscriber)
    return CampaignOutcome(outcome.status, outcome.reason, analyses)


def done_in_file(plan: CampaignPlan, out_path: Path) -> DoneBefore:
    """The points of ``plan``'s sequence that the campaign file ``out_path`` holds done already and
    their estimated duration (a complete sweep or hammer run counts whole); nothing when there is no
    file."""
    if not Path(out_path).exists():
        return DoneBefore()
    steps = {
        Engine.run_id(plan.sequence, i): step
        for i, step in enumerate(plan.sequence.steps)
        if is_measurement(step)
    }
    points, estimated_s = 0, 0.0
    with open_campaign(out_path) as campaign:
        for run in campaign.runs:
            step = steps.get(run.run_id)
            if step is None:
                continue
            done = run.completed_point_indices()
            points += len(done)
            if isinstance(step, SineDwell | DwellGrid | FreeRun):
                dwells = (step,) if isinstance(step, SineDwell) else step.dwells()
                # an adaptive grid's added points are beyond its planned dwells and its estimate
                estimated_s += sum(dwells[i].duration_s for i in done if i < len(dwells))
            elif run.status == "complete":
                estimated_s += step.estimated_duration_s
    return DoneBefore(points, estimated_s)


def initial_knowledge(config: BenchConfig) -> CampaignKnowledge:
    """What a campaign knows before its first run: the configuration's masses and the sensor's
    assumed eigenfrequency."""
    return CampaignKnowledge(
        sensor=WfsSensor(mass_kg=config.masses.sensor_kg, eigenfrequency_hz=DEFAULT_SENSOR_EIGENFREQUENCY_HZ),
        wheel_mass_kg=config.masses.wheel_below_sensor_kg,
    )


def _campaign_writer(plan: CampaignPlan, out_path: Path, exists: bool) -> CampaignWriter:
    if exists:
        return CampaignWriter.open_append(out_path)
    return CampaignWriter.create(
        out_path,
        software_version=software_version(),
        config_toml=plan.config_text,
        sequence_toml=plan.sequence_text,
        sequence_name=plan.sequence.name,
        config_name=plan.config.source,
    )


def _run_ids(path: Path) -> set[str] | None:
    """The run ids of the campaign file at ``path``, None when there is no file (StoreError when
    the file is no campaign file)."""
    if not path.exists():
        return None
    with open_campaign(path) as campaign:
        return {run.run_id for run in campaign.runs}
