"""What stands on the simulated bench, changed the way a technician changes the real one.

Removing or fitting the wheel, inflating the tyre, putting the car on the four posts, setting its
dampers and striking the hammer are operator actions, not device commands: the run engine asks for
them with a prompt and records the answer. On the real bench a person acts; on the simulated bench
:class:`SimulatedOperator` applies the answer to :class:`SimulatedWorld`, which mounts the matching
:class:`~bench.models.setup.BenchSetup` on the simulated bench (so answering 2.4 bar to "set
2.5 bar" gives the plant a 2.4 bar tyre). The engine's device contracts never see any of it.

Every change of setup happens at rest: the world refuses it while the actuator moves.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np
from scipy.optimize import minimize_scalar

from bench.models.benches import TyreModel
from bench.models.parameters import (
    TYRE_PRESSURE_RANGE_BAR,
    DamperNonlinearity,
    Rig,
    Suspension,
    TyreNonlinearity,
    tyre_at_pressure,
)
from bench.models.setup import BenchKind, BenchSetup
from sequences.steps import PROMPT_ACTIONS, PromptAction
from simulators.bench_sim import SimulatedBench
from simulators.plant import HalfSinePulse

#: Damper settings of the quarter car's shock absorber (Ns/m): the default Suspension's 3000 Ns/m
#: is the middle-firm setting of the paper's test vehicle; soft and firm one step either side.
DAMPER_SETTINGS_NS_PER_M = {"soft": 2000.0, "medium": 3000.0, "firm": 4500.0}
#: The shaker's plate and the four-post bench's post (m_comp of each free run).
SHAKER_RIG = Rig(plate_mass_kg=12.0)
POST_RIG = Rig(plate_mass_kg=15.0)
#: A hammer blow: a modally tuned hammer with a steel tip, about 3 kN over 0.15 ms.
HAMMER_PEAK_N = 3000.0
HAMMER_WIDTH_S = 1.5e-4


#: The grid (s of bench time) of a drift's seeded random wander: a Brownian path sampled at these
#: steps and interpolated between them, so that it does not depend on the bench's block size.
WANDER_STEP_S = 0.1
#: The smallest relative change of the stiffness that is applied to the plant (re-linearising the
#: tyre costs a rebuild of the plant's system; a change this small moves a resonance by 0.025 %).
DRIFT_RESOLUTION = 5e-4


@dataclass(frozen=True)
class TyreDrift:
    """The tyre's stiffness drifting as the bench runs (a tyre warming up, slowly losing pressure):
    ``k(t) = k0 (1 + rate_per_s t + wander_per_sqrt_s W(t))``, ``t`` the bench time since the drift
    began and ``W`` a Brownian path of seed ``seed`` (deterministic in bench time)."""

    rate_per_s: float
    wander_per_sqrt_s: float = 0.0
    seed: int = 0

    def factor(self, t_s: float, path: list[float]) -> float:
        """The stiffness over its nominal value at ``t_s``; ``path`` caches the wander's grid values
        (extended as needed, from the seed)."""
        if self.wander_per_sqrt_s == 0.0:
            return 1.0 + self.rate_per_s * t_s
        k = int(t_s / WANDER_STEP_S) + 2
        if len(path) < k:
            steps = np.random.default_rng(self.seed).standard_normal(max(k, 2 * len(path)))
            path[:] = list(np.r_[0.0, np.cumsum(steps)[:-1]] * np.sqrt(WANDER_STEP_S))
        wander = float(np.interp(t_s / WANDER_STEP_S, np.arange(len(path)), path))
        return 1.0 + self.rate_per_s * t_s + self.wander_per_sqrt_s * wander


def wfs_contact_peak_hz(setup: BenchSetup, amplitude_m: float, band_hz: tuple[float, float]) -> float:
    """Where ``|F_WFS / F_contact|`` of ``setup`` peaks within ``band_hz`` (the tread resonance on
    the shaker), the tyre linearised at ``amplitude_m`` as the plant does: the simulated world's
    truth, to 1 mHz, for what a tracked dwell finds."""

    def ratio(freq_hz: float) -> float:
        network = setup.operating_network(freq_hz, amplitude_m)
        response = network.frequency_response(freq_hz, outputs=("f_wfs", "f_contact"))
        return abs(response["f_wfs"][0] / response["f_contact"][0])

    found = minimize_scalar(lambda f: -ratio(f), bounds=band_hz, method="bounded", options={"xatol": 1e-3})
    return float(found.x)


def drifted(setup: BenchSetup, factor: float) -> BenchSetup:
    """``setup`` with its tyre's stiffness ``factor`` times its own."""
    return setup.with_tyre(replace(setup.tyre, stiffness_n_per_m=setup.tyre.stiffness_n_per_m * factor))


class WorldBench(StrEnum):
    SHAKER = "shaker"  # the shaker bench: a wheel on the sensor, or the plate alone
    FOUR_POST = "four_post"  # the four-post bench: the car on the posts, or the posts alone


class SimulatedWorld:
    """The simulated bench and what is mounted on it.

    State: which bench (shaker or four-post), whether the wheel is fitted (shaker) or the car stands
    on the posts (four-post), the tyre pressure, the damper setting, and whether the bare sensor is
    on its hammer-test foundation. The setup the plant simulates follows from it:

    ============================  =========================================================
    shaker, wheel fitted          ``SHAKER`` with the tyre at the set pressure
    shaker, wheel removed         ``FREE_RUN`` of the shaker plate (m_comp)
    four-post, car on the posts   ``QUARTER_CAR`` with the tyre at the pressure, the damper
    four-post, car off the posts  ``FREE_RUN`` of the post
    bare sensor (hammer)          ``HAMMER``: after :meth:`strike_hammer` with no specimen on it
    ============================  =========================================================

    The tyre model and its non-linearity are fixed at construction. Each action mounts the new
    setup on the bench at once (:meth:`SimulatedBench.mount`: the sensor realism, noise stream and
    output rate carry on) and raises RuntimeError while the actuator moves, ValueError when the
    action makes no sense on this bench (fitting a wheel on the four-post bench) or its value is out
    of range.
    """

    def __init__(
        self,
        bench: SimulatedBench,
        *,
        kind: WorldBench | str = WorldBench.SHAKER,
        pressure_bar: float = 2.5,
        specimen_mounted: bool = True,
        damper: str = "medium",
        model: TyreModel | None = None,
        nonlinear: bool = True,
        damper_nonlinear: bool = False,
    ) -> None:
        self.bench = bench
        self.kind = WorldBench(kind)
        self.model = TyreModel(model) if model is not None else self._default_model(self.kind)
        self.nonlinearity = TyreNonlinearity() if nonlinear else None
        self.damper_law = DamperNonlinearity() if damper_nonlinear else None
        self.pressure_bar = float(pressure_bar)
        self.specimen_mounted = specimen_mounted
        self.damper = damper
        self.bare_sensor = False
        self._check_pressure(self.pressure_bar)
        self._check_damper(damper)
        self._mount()

    @staticmethod
    def _default_model(kind: WorldBench) -> TyreModel:
        """Model 2 on the shaker (the paper's best fit there), Model 3 on the four posts."""
        return TyreModel.WHEEL_TREAD if kind is WorldBench.SHAKER else TyreModel.WHEEL_TREAD_SIDEWALL

    # ------------------------------------------------------------------ the present setup
    @property
    def setup(self) -> BenchSetup:
        """The setup the world's state describes (mounted on the bench after every action)."""
        if self.bare_sensor:
            return BenchSetup.paper_hammer()
        tyre = tyre_at_pressure(self.pressure_bar)
        if self.kind is WorldBench.SHAKER:
            if not self.specimen_mounted:
                return BenchSetup(BenchKind.FREE_RUN, rig=SHAKER_RIG)
            return BenchSetup(
                BenchKind.SHAKER, self.model, tyre, rig=SHAKER_RIG, nonlinearity=self.nonlinearity
            )
        if not self.specimen_mounted:
            return BenchSetup(BenchKind.FREE_RUN, rig=POST_RIG)
        damping_ns_per_m = DAMPER_SETTINGS_NS_PER_M[self.damper]
        suspension = Suspension(damping_ns_per_m=damping_ns_per_m, damper=self.damper_law)
        return BenchSetup(
            BenchKind.QUARTER_CAR,
            self.model,
            tyre,
            suspension=suspension,
            rig=POST_RIG,
            nonlinearity=self.nonlinearity,
        )

    def _mount(self) -> None:
        self.bench.mount(self.setup)

    def _change(self, **state: object) -> None:
        """Apply a change of state and mount it; the state is unchanged if the bench refuses."""
        before = {name: getattr(self, name) for name in state}
        for name, value in state.items():
            setattr(self, name, value)
        try:
            self._mount()
        except RuntimeError:
            for name, value in before.items():
                setattr(self, name, value)
            raise

    def _require(self, kind: WorldBench, action: str) -> None:
        if self.kind is not kind:
            raise ValueError(f"{action}: not on the {self.kind.value} bench, only on the {kind.value}")

    @staticmethod
    def _check_pressure(pressure_bar: float) -> None:
        low, high = TYRE_PRESSURE_RANGE_BAR
        if not low <= pressure_bar <= high:
            raise ValueError(f"set_tyre_pressure: {pressure_bar} bar is outside {low}-{high} bar")

    @staticmethod
    def _check_damper(setting: str) -> None:
        if setting not in DAMPER_SETTINGS_NS_PER_M:
            known = ", ".join(DAMPER_SETTINGS_NS_PER_M)
            raise ValueError(f"set_damper: unknown setting {setting!r}; known: {known}")

    # ------------------------------------------------------------------ operator actions
    def remove_wheel(self) -> None:
        """Take the wheel off the shaker: the plate runs alone (the free run)."""
        self._require(WorldBench.SHAKER, PromptAction.REMOVE_WHEEL)
        self._change(specimen_mounted=False, bare_sensor=False)

    def fit_wheel(self) -> None:
        """Fit the wheel (at the present tyre pressure) on the shaker."""
        self._require(WorldBench.SHAKER, PromptAction.FIT_WHEEL)
        self._change(specimen_mounted=True, bare_sensor=False)

    def car_on_posts(self) -> None:
        """Drive the car onto the four posts (the quarter car at the tyre pressure and damper)."""
        self._require(WorldBench.FOUR_POST, PromptAction.CAR_ON_POSTS)
        self._change(specimen_mounted=True, bare_sensor=False)

    def car_off_posts(self) -> None:
        """Drive the car off: the post runs alone (the post's free run)."""
        self._require(WorldBench.FOUR_POST, PromptAction.CAR_OFF_POSTS)
        self._change(specimen_mounted=False, bare_sensor=False)

    def set_tyre_pressure(self, pressure_bar: float) -> None:
        """Inflate the tyre to ``pressure_bar`` (its stiffness from :func:`tyre_at_pressure`)."""
        pressure_bar = float(pressure_bar)
        self._check_pressure(pressure_bar)
        self._change(pressure_bar=pressure_bar)

    def set_damper(self, setting: str) -> None:
        """Set the quarter car's damper to one of :data:`DAMPER_SETTINGS_NS_PER_M`."""
        self._require(WorldBench.FOUR_POST, PromptAction.SET_DAMPER)
        self._check_damper(setting)
        self._change(damper=setting)

    def drift_tyre(self, drift: TyreDrift | None) -> None:
        """Let the mounted tyre's stiffness drift from now on as ``drift`` says (None: stop it); the
        drift ends with the next action that mounts anything. ValueError without a tyre mounted."""
        if drift is None:
            self.bench.drift(None)
            return
        if not self.setup.has_tyre:
            raise ValueError("drift_tyre: no tyre on the bench")
        path: list[float] = []
        applied: list = [1.0, self.bench.plant.setup]  # the factor in force and its setup

        def setup_at(t_s: float) -> BenchSetup:
            factor = drift.factor(t_s, path)
            if abs(factor - applied[0]) >= DRIFT_RESOLUTION:
                applied[:] = [factor, drifted(self.setup, factor)]
            return applied[1]

        self.bench.drift(setup_at)

    def strike_hammer(self, peak_n: float = HAMMER_PEAK_N, width_s: float = HAMMER_WIDTH_S) -> None:
        """Strike the bare sensor: a half-sine blow of ``peak_n`` lasting ``width_s`` from the next sample.

        The sensor must carry no specimen (wheel removed, car off the posts); the first blow puts it
        on its hammer-test foundation (the ``HAMMER`` setup), where it stays until the next action.
        """
        if self.specimen_mounted:
            specimen = "wheel" if self.kind is WorldBench.SHAKER else "car"
            raise ValueError(f"strike_hammer: the hammer test is on the bare sensor: remove the {specimen}")
        if not peak_n > 0 or not width_s > 0:
            raise ValueError(f"strike_hammer: peak {peak_n} N and width {width_s} s must be positive")
        if not self.bare_sensor:
            self._change(bare_sensor=True)
        self.bench.strike(HalfSinePulse(peak_n, width_s=width_s, delay_s=0.0, record_s=width_s))


class SimulatedOperator:
    """Applies the answers to operator prompts to the simulated world (simulated mode only).

    ``apply(action, answer)`` maps a Prompt's ``action`` to the world: ``set_tyre_pressure``
    (answer in bar), ``set_damper`` (answer a setting), ``remove_wheel``, ``fit_wheel``,
    ``car_on_posts``, ``car_off_posts`` and ``strike_hammer`` (answer a confirmation; False means
    the operator did not act; for ``strike_hammer`` a number is the blow's peak force in N).
    """

    def __init__(self, world: SimulatedWorld) -> None:
        self.world = world

    def apply(self, action: str, answer: float | str | bool | None) -> None:
        """Do what the operator was asked, with the answer given. ValueError for an unknown action."""
        if action not in PROMPT_ACTIONS:
            raise ValueError(f"unknown operator action {action!r}; known: {', '.join(PROMPT_ACTIONS)}")
        world = self.world
        if action == PromptAction.SET_TYRE_PRESSURE:
            world.set_tyre_pressure(float(answer))  # type: ignore[arg-type]
        elif action == PromptAction.SET_DAMPER:
            world.set_damper(str(answer))
        elif answer is False:
            return  # a confirmation declined: nothing was done
        elif action == PromptAction.STRIKE_HAMMER:
            if isinstance(answer, int | float) and not isinstance(answer, bool):
                world.strike_hammer(float(answer))
            else:
                world.strike_hammer()
        else:
            getattr(world, action)()
