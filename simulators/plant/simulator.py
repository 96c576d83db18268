"""Time-domain simulation of a bench: actuator, specimen network and sensors, block by block.

The linear part is exact: the continuous state space (servo actuator coupled to the mechanical
network it drives -> hub accelerometer) is discretised for inputs that are linear between samples
and stepped in modal coordinates with one all-pole recursion per mode (``scipy.signal.lfilter``),
never a Python loop over samples. A non-linear tyre is handled as an equivalent linear system per
operating point (see :class:`bench.models.parameters.TyreNonlinearity`), and so is the servo
valve's flow limit (see :class:`simulators.plant.actuator.ServoActuator`): the physical state
carries over when the operating point changes.

The plant runs at ``oversampling`` times the output rate (10 kHz for a 1 kHz WFS stream), where
noise and quantisation act like the WFS's own converters, then decimates.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import matrix_balance
from scipy.signal import lfilter

from bench.models.linear_system import DiscreteSystem, LinearSystem
from bench.models.network import MechanicalNetwork
from bench.models.setup import BenchKind, BenchSetup, DriveDensity
from simulators.plant.actuator import LOAD_OUTPUT, Actuator, ServoActuator
from simulators.plant.excitation import Waveform
from simulators.plant.sensors import Decimator, SensorRealism, accelerometer_system

#: Output channels: name -> network output it measures.
_MEASURED = {
    "z_base_m": "z_base",
    "f_plate_n": "f_plate",
    "fz_wfs_n": "f_wfs",
    "a_hub_m_s2": "a_hub",
    "f_contact_n": "f_contact",
}
_HAMMER_CHANNELS = ("fz_wfs_n", "f_hammer_n")
#: A non-linear tyre is re-linearised when the excitation frequency has moved by this fraction.
_RESCHEDULE_FRACTION = 0.02
_ONE = np.ones(1)
#: ``simulate`` reports a waveform's operating point at this interval.
_RESCHEDULE_CHECK_S = 0.05


class _ModalStepper:
    """Exact first-order-hold stepping of a single-input discrete system, mode by mode, in real
    arithmetic.

    Each mode obeys ``xi[k] = lam xi[k-1] + b1 u[k] + b0 u[k-1]``. Over a block, xi is the
    response to the block's input from rest plus the free decay ``r lam^k`` of what the block
    inherits (``r = lam xi[-1] + b0 u[-1]``). A conjugate pair is stepped once: its forced part
    is the real all-pole biquad ``w = u / ((1 - lam z^-1)(1 - conj(lam) z^-1))`` with the three-tap
    numerator ``xi = n0 w[k] + n1 w[k-1] + n2 w[k-2]``; a real mode uses a first-order section.
    The free decays ``Re(lam^k)``, ``Im(lam^k)`` depend only on the block length and are cached.
    So the per-sample work is one real all-pole ``lfilter`` section per mode and two matrix products, and
    only the physical state is kept between blocks: the system may change between any two blocks.
    """

    def __init__(self, dsys: DiscreteSystem):
        if dsys.g0.shape[1] != 1:
            raise ValueError("modal stepping is implemented for single-input systems")
        # Balance first: states range from metres to m/s^3, which wrecks the eigenvector basis.
        balanced, (scale, _) = matrix_balance(dsys.phi, permute=False, separate=True)
        lam, modes = np.linalg.eig(balanced)
        if modes.size and np.linalg.cond(modes) > 1e8:
            raise ValueError("state matrix is (nearly) defective: modal stepping would be inaccurate")
        v = scale[:, None] * modes
        v_inv = np.linalg.inv(modes) / scale[None, :] if modes.size else modes
        tiny = 1e-12 * np.abs(lam)
        keep = (lam.imag > tiny) | (np.abs(lam.imag) <= tiny)  # one of each pair, and real modes
        self.lam = lam[keep]
        paired = np.abs(self.lam.imag) > tiny[keep]
        weight = np.where(paired, 2.0, 1.0)
        self.V_inv = v_inv[keep]
        self.b0 = (self.V_inv @ dsys.g0)[:, 0]
        b1 = (self.V_inv @ dsys.g1)[:, 0]
        conj = np.conj(self.lam)
        a1 = np.where(paired, -2 * self.lam.real, -self.lam.real)
        a2 = np.where(paired, np.abs(self.lam) ** 2, 0.0)
        self.denominators = [np.array([1.0, a1[i], a2[i]]) for i in range(self.lam.size)]
        num = np.stack(
            [b1, np.where(paired, self.b0 - b1 * conj, self.b0), np.where(paired, -self.b0 * conj, 0)]
        )
        # every output and state variable as real combinations of the taps w[k], w[k-1], w[k-2]
        out_modes = (dsys.C @ v[:, keep]) * weight
        state_modes = v[:, keep] * weight
        self.out_taps = (out_modes[:, :, None] * num.T[None]).real.reshape(dsys.C.shape[0], -1)
        self.state_taps = (state_modes[:, :, None] * num.T[None]).real.reshape(v.shape[0], -1)
        self.out_modes, self.state_modes = out_modes, state_modes
        self.D = dsys.D[:, 0] if np.any(dsys.D) else None  # no feedthrough from a 3rd-order actuator
        self._decay: np.ndarray | None = None

    def _decays(self, n: int) -> np.ndarray:
        """Re(lam^k) and Im(lam^k) for k < n, stacked (2 * modes x n); cached per block length."""
        if self._decay is None or self._decay.shape[1] != n:
            powers = np.ones((self.lam.size, n), dtype=complex)
            powers[:, 1:] = self.lam[:, None]
            powers = np.cumprod(powers, axis=1)  # lam^k, accurate to ~k * eps
            decay = np.concatenate([powers.real, powers.imag])
            decay[np.abs(decay) < 1e-30] = 0.0  # decayed: and subnormal numbers are slow
            self._decay = decay
        return self._decay

    def run(self, x_prev: np.ndarray, u_prev: float, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Outputs for the input samples ``u`` after state ``x_prev`` under input ``u_prev``.

        Returns the outputs (outputs x samples) and the state at the last sample.
        """
        taps = np.zeros((3 * self.lam.size, u.size))
        for i, denominator in enumerate(self.denominators):
            w = lfilter(_ONE, denominator, u)  # all-pole section from rest
            taps[3 * i] = w
            taps[3 * i + 1, 1:] = w[:-1]
            taps[3 * i + 2, 2:] = w[:-2]
        inherited = self.lam * (self.V_inv @ x_prev) + self.b0 * u_prev
        out_free = self.out_modes * inherited
        state_free = self.state_modes * inherited
        decay = self._decays(u.size)
        y = self.out_taps @ taps + np.hstack([out_free.real, -out_free.imag]) @ decay
        if self.D is not None:
            y += np.outer(self.D, u)
        x_last = self.state_taps @ taps[:, -1] + np.hstack([state_free.real, -state_free.imag]) @ decay[:, -1]
        return y, x_last


class PlantSimulator:
    """A simulated bench producing what its sensors would read, block by block.

    ``advance(command)`` takes the actuator displacement command (m) at the internal rate (the
    hammer force in N for the hammer setup) and returns each channel at the output rate. With
    decimation on, outputs lag the command by :attr:`latency_samples` output samples (the group
    delay of the anti-alias filter, as in a real acquisition); all channels share that delay.
    ``f_contact_n`` is the true contact force: a reference for tests, not a sensor.
    :attr:`converter_fz_n` holds the last advance's WFS Fz at the internal (converter) rate, noise
    and quantisation included, before the anti-alias filter: what a triggered capture buffers;
    :attr:`converter_z_base_m` the actuator's displacement at the internal rate, noise-free (what the
    controller's own transducer samples).
    """

    def __init__(
        self,
        setup: BenchSetup,
        realism: SensorRealism | None = None,
        actuator: Actuator | None = None,
        output_rate_hz: float = 1000.0,
        oversampling: int = 10,
    ):
        self.setup = setup
        self.realism = realism or SensorRealism()
        self.actuator: Actuator = actuator or ServoActuator()
        self.output_rate_hz = float(output_rate_hz)
        self.oversampling = int(oversampling)
        self.internal_rate_hz = self.output_rate_hz * self.oversampling
        self.reset()

    # ------------------------------------------------------------------ system assembly
    def _build_stepper(self, network: MechanicalNetwork, flow_factor: float) -> _ModalStepper:
        if self._hammer:
            system = network.state_space(outputs=("f_wfs",))
        else:
            wanted = [o for o in _MEASURED.values() if o in network.output_names]
            system = self.actuator.drive(network.state_space(outputs=wanted), flow_factor)
            if self.realism.accelerometer_dynamics and "a_hub" in wanted:
                system = system.then(accelerometer_system(self.realism.accelerometer_bandwidth_hz))
                wanted[wanted.index("a_hub")] = "a_hub_sensor"
            system = system.select(wanted)
        self._network, self._flow_factor = network, flow_factor
        self._system = system
        self._rows = self._channel_rows(system)
        return _ModalStepper(system.discretize_foh(1.0 / self.internal_rate_hz))

    def _channel_rows(self, system: LinearSystem) -> list[int | None]:
        """Index of the system output behind each channel (None: the channel reads zero signal)."""
        if self._hammer:
            return [0, None]
        rows: list[int | None] = []
        for channel, network_output in _MEASURED.items():
            output = network_output
            if channel == "a_hub_m_s2" and "a_hub_sensor" in system.outputs:
                output = "a_hub_sensor"
            rows.append(system.outputs.index(output) if output in system.outputs else None)
        return rows

    @staticmethod
    def _load_n_per_m(network: MechanicalNetwork, freq_hz: float) -> complex:
        """The actuator's load: plate force per metre of base displacement at ``freq_hz``."""
        return complex(network.frequency_response(freq_hz, outputs=(LOAD_OUTPUT,))[LOAD_OUTPUT][0])

    def _operating_solution(
        self, freq_hz: float, amplitude_m: float, density: DriveDensity | None = None
    ) -> tuple[MechanicalNetwork, float, complex]:
        """Network, valve flow factor and base gain for a sine command at an operating point.

        The achieved base amplitude depends on the load, and a non-linear tyre's load on the base
        amplitude: the tyre is linearised for the base amplitude the actuator achieves against the
        nominal tyre, then the flow factor and gain follow from the linearised load. The remaining
        inconsistency is the gain's change with the tyre's linearisation times the linearisation's
        change with amplitude, both small (well below 1e-3 of the amplitude). Deterministic: the
        same operating point always gives the same solution.
        """
        network = self._nominal_network
        if self.setup.nonlinear:
            nominal_load = self._load_n_per_m(network, freq_hz)
            nominal_flow = self.actuator.flow_factor(freq_hz, amplitude_m, nominal_load)
            nominal_gain = self.actuator.gain(freq_hz, nominal_load, nominal_flow)
            network = self.setup.operating_network(freq_hz, abs(nominal_gain) * amplitude_m, density)
        load = self._load_n_per_m(network, freq_hz)
        flow = self.actuator.flow_factor(freq_hz, amplitude_m, load)
        return network, flow, self.actuator.gain(freq_hz, load, flow)

    def set_operating_point(
        self, freq_hz: float, amplitude_m: float, density: DriveDensity | None = None
    ) -> None:
        """Tell the plant the excitation's frequency and commanded amplitude, and a broadband drive's
        ``density`` (None: a sine's), for which a non-linear damper is linearised statistically.

        A non-linear tyre is linearised for the base amplitude the actuator achieves at that
        frequency, and the servo valve's flow limit becomes its equivalent gain there. A point
        within 2 % in frequency of the current one at the same amplitude keeps the current
        linearisation, so callers may report the operating point as often as they like (every block
        of a sweep). The discrete system is rebuilt only when the network or the flow factor
        changes; no effect on the hammer setup or without excitation.
        """
        if self._hammer or freq_hz <= 0 or amplitude_m <= 0:
            return
        if self._operating_point is not None:
            current_hz, current_amplitude_m, current_density = self._operating_point
            if abs(freq_hz - current_hz) <= _RESCHEDULE_FRACTION * current_hz and (
                amplitude_m == current_amplitude_m and density is current_density
            ):
                return
        self._operating_point = (float(freq_hz), float(amplitude_m), density)
        network, flow_factor, _ = self._operating_solution(freq_hz, amplitude_m, density)
        if network is not self._network or flow_factor != self._flow_factor:
            self._stepper = self._build_stepper(network, flow_factor)

    def base_gain(self, freq_hz: float, amplitude_m: float) -> complex:
        """Achieved base displacement per unit command for a sine command at an operating point."""
        if self._hammer:
            raise ValueError("the hammer setup has no actuator")
        return self._operating_solution(freq_hz, amplitude_m)[2]

    def exact_response(self, freq_hz: float, amplitude_m: float) -> dict[str, complex]:
        """The plant's exact response per metre of base displacement at an operating point.

        Keys are network outputs (``f_wfs``, ``f_contact``, ``f_plate``, ``a_hub``, ``z_rim``, ...);
        ``amplitude_m`` is the commanded amplitude as for :meth:`set_operating_point`, and
        :meth:`base_gain` the base displacement per unit command there.
        """
        network = self._nominal_network if self._hammer else self._operating_solution(freq_hz, amplitude_m)[0]
        return {k: complex(v[0]) for k, v in network.frequency_response(freq_hz).items()}

    def set_output_rate(self, output_rate_hz: float) -> None:
        """Change the output rate at the same internal (converter) rate; the plant's state carries over.

        Only rates whose oversampling ``internal_rate_hz / output_rate_hz`` is a whole number are
        possible (ValueError otherwise); the decimation filter is rebuilt for the new factor and
        continues from the recent input, and :attr:`latency_samples` stays in output samples.
        """
        ratio = self.internal_rate_hz / output_rate_hz if output_rate_hz > 0 else 0.0
        oversampling = round(ratio)
        if oversampling < 1 or abs(ratio - oversampling) > 1e-9 * ratio:
            raise ValueError(
                f"output rate {output_rate_hz:g} Hz: {self.internal_rate_hz:g} Hz / rate not a whole number"
            )
        self._decimator = self._decimator.with_factor(oversampling)
        self.latency_samples = self._decimator.latency_samples
        self.oversampling = oversampling
        self.output_rate_hz = self.internal_rate_hz / oversampling

    # ------------------------------------------------------------------ stepping
    def advance(self, command: np.ndarray) -> dict[str, np.ndarray]:
        """Advance by ``len(command)`` internal samples; return the channels at the output rate."""
        u = np.asarray(command, dtype=float).ravel()
        if u.size == 0 or u.size % self.oversampling:
            raise ValueError(f"command length must be a positive multiple of {self.oversampling}")
        if not np.all(np.isfinite(u)):
            raise ValueError("command contains NaN or infinite values")
        y, self._x = self._stepper.run(self._x, self._u_prev, u)
        self._u_prev = float(u[-1])
        internal = np.zeros((len(self.channels), u.size))
        for i, row in enumerate(self._rows):
            if row is not None:
                internal[i] = y[row]
        if self._hammer:
            internal[1] = u
        self._wfs_converter(internal)
        self.converter_fz_n = internal[self.channels.index("fz_wfs_n")].copy()
        z_row = self.channels.index("z_base_m") if "z_base_m" in self.channels else None
        self.converter_z_base_m = internal[z_row].copy() if z_row is not None else np.zeros(u.size)
        out = self._decimator(internal)
        self._output_noise(out)
        if not self._hammer and self.realism.accelerometer_dynamics:
            out[self.channels.index("a_hub_m_s2")] += self.realism.accelerometer_offset_m_s2
        return dict(zip(self.channels, out, strict=True))

    def _wfs_converter(self, internal: np.ndarray) -> None:
        """The WFS converter at the internal rate: its noise, then quantisation (in place)."""
        r, i = self.realism, self.channels.index("fz_wfs_n")
        if r.noise:
            internal[i] += r.wfs_noise_n * self._rng.standard_normal(internal.shape[1])
        if r.quantisation:
            internal[i] = np.round(internal[i] / r.wfs_step_n) * r.wfs_step_n

    def _output_noise(self, out: np.ndarray) -> None:
        """Noise of the other transducers, rms at the output rate (in place)."""
        r = self.realism
        if not r.noise or self._hammer:
            return
        levels = {
            "z_base_m": r.displacement_noise_m,
            "f_plate_n": r.load_cell_noise_n,
            "a_hub_m_s2": r.accelerometer_noise_m_s2,
        }
        for channel, rms in levels.items():
            out[self.channels.index(channel)] += rms * self._rng.standard_normal(out.shape[1])

    def reset(self) -> None:
        """Back to rest: zero state, the nominal tyre, fresh filters and the seed's first noise sample."""
        self._rng = np.random.default_rng(self.realism.seed)
        self.mount(self.setup)

    def mount(self, setup: BenchSetup) -> None:
        """Put ``setup`` on the bench, at rest: what a technician changes between runs.

        The mechanical state starts from rest (the specimen was just mounted), the filters start
        fresh (the channels may change: the hammer setup has its own), the operating point is
        forgotten. The sensor realism, the actuator, the output rate and the noise stream carry on.
        """
        self.setup = setup
        self._hammer = setup.kind is BenchKind.HAMMER
        self.channels = _HAMMER_CHANNELS if self._hammer else tuple(_MEASURED)
        self._nominal_network = setup.network()
        self._stepper = self._build_stepper(self._nominal_network, 1.0)
        self._to_rest()

    def _to_rest(self) -> None:
        """What is mounted back at rest: zero state, fresh filters, the operating point forgotten.
        The discrete system stays: :meth:`set_operating_point` rebuilds it when the next operating
        point needs another, as it would after a :meth:`mount`."""
        self._decimator = Decimator(self.oversampling, len(self.channels), filtered=self.realism.decimation)
        self.latency_samples = self._decimator.latency_samples
        self._operating_point: tuple[float, float, DriveDensity | None] | None = None
        self._x = np.zeros(len(self._system.states))
        self._u_prev = 0.0
        self.converter_fz_n = np.zeros(0)
        self.converter_z_base_m = np.zeros(0)

    def retune(self, setup: BenchSetup) -> None:
        """Change the values of what is mounted while it moves (a tyre warming up), not what it is:
        the network keeps its states, so the mechanical state carries over; the operating point is
        linearised anew at the next :meth:`set_operating_point`. ValueError for another kind of
        setup (that is a :meth:`mount`, at rest)."""
        if setup.kind is not self.setup.kind or setup.model is not self.setup.model:
            raise ValueError(f"retune keeps the kind and model of the setup ({self.setup.kind.value})")
        self.setup = setup
        self._nominal_network = setup.network()
        operating, self._operating_point = self._operating_point, None
        if operating is None:
            self._stepper = self._build_stepper(self._nominal_network, 1.0)
        else:
            self.set_operating_point(*operating)

    # ------------------------------------------------------------------ offline runs
    def simulate(self, waveform: Waveform, extra_s: float = 0.0) -> dict[str, np.ndarray]:
        """Run a whole waveform from rest; channels aligned with the waveform's time axis.

        The record covers ``waveform.duration_s + extra_s``; a non-linear tyre is rescheduled as
        a sweep's frequency moves. Returns the channels and ``t_s``. The mechanical state and the
        filters start from rest; the noise stream carries on from the call before, as a bench's
        noise does from one dwell to the next (the dwells of one seed share no noise; the same
        calls on a simulator of the same seed give the same records).
        """
        self._to_rest()
        n_out = round((waveform.duration_s + extra_s) * self.output_rate_hz)
        n_total = n_out + self.latency_samples
        t_internal = np.arange(n_total * self.oversampling) / self.internal_rate_hz
        command = waveform.value(t_internal)
        chunk = max(1, round(_RESCHEDULE_CHECK_S * self.output_rate_hz)) * self.oversampling
        starts = np.arange(0, command.size, chunk)
        freqs_hz = np.array([waveform.frequency_hz(t_internal[i]) for i in starts])
        # the operating point is told at each chunk; chunks at the frequency of the one before (a
        # dwell's, all of them) are stepped in one block, which only its noise draws tell apart
        moved = np.flatnonzero(np.diff(freqs_hz) != 0) + 1
        blocks: list[dict[str, np.ndarray]] = []
        for first, stop in zip(np.r_[0, moved], np.r_[moved, starts.size], strict=True):
            self.set_operating_point(freqs_hz[first], waveform.amplitude, getattr(waveform, "density", None))
            blocks.append(self.advance(command[starts[first] : min(starts[stop - 1] + chunk, command.size)]))
        record = {c: np.concatenate([b[c] for b in blocks])[self.latency_samples :] for c in self.channels}
        record["t_s"] = np.arange(n_out) / self.output_rate_hz
        return record
