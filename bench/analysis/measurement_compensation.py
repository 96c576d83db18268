"""A measured WFS force (a road drive, any record of Fz and hub acceleration) compensated to the
contact force with the model a campaign identified, and a 95 % band per sample.

The compensated force is the model-based inverse of :mod:`bench.analysis.compensation`,
``F_contact = G_F F_wfs + G_A a_hub``, realised as two FIR filters at the measurement's sample rate
(the same band, duration and latency as the campaign's compensator), the hub acceleration's path
advanced by the accelerometer's lag where the campaign measured it. Its uncertainty has three parts,
each propagated through the filters sample by sample:

- **the identified parameters** (the tyre fit's covariance, the wheel mass's and the sensor's where
  the campaign gives them), linearised: the filters' taps are linear in their target response, so
  their derivative with respect to each parameter (central differences of the design,
  :data:`RELATIVE_STEP`) is a filter too, and the force's sensitivity ``s_j[n]`` to parameter ``j``
  is that filter applied to the inputs. The variance is ``s[n]^T C s[n]``. PyDynamic's
  ``FIRuncFilter`` propagates a covariance of FIR taps the same way; here the taps' covariance
  follows from the parameters';
- **the tyre's amplitude and rate dependence**: the campaign identified the tyre at several
  amplitudes (1 / 2 / 5 mm), which differ where the rubber's friction damping matters (near the
  tread resonance), and a road's tyre deflection is none of them; nor need a road's tyre follow
  the rubber terms the bench measured. The compensator of each alternative (each other amplitude,
  and the chosen model fitted without rubber terms) gives a force too; the largest deviation from the
  chosen one is taken as the half-width of a rectangular distribution (variance
  ``max_j d_j[n]^2 / 3``);
- **the sensors' noise**, white at the levels the campaign's dwells show (the residual rms of
  ``fz_wfs_n`` and ``a_hub_m_s2`` on the shaker), through the filters: ``sigma_F^2 sum h_F^2 +
  sigma_a^2 sum h_A^2``, the same for every sample.

The 95 % half-width is 1.96 times the combined standard uncertainty. What none of these covers: a
tyre that is not the campaign's (another pressure is refused), an accelerometer other than the one
the campaign characterised, what lies outside the valid band.

All filters run together, block by block, by overlap-save FFT convolution
(:class:`CompensationStream`): memory is a few blocks whatever the record's length.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from dataclasses import dataclass, fields, replace
from typing import NamedTuple

import numpy as np

from bench.analysis.blockwise import Record
from bench.analysis.compensation import ModelCompensator, design_model_compensator
from bench.analysis.lsq import Z95
from bench.analysis.shaker_models import RubberTerms
from bench.analysis.validation import AnalysisInputError
from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor

#: Relative step of the central differences of the filter design with respect to a parameter.
RELATIVE_STEP = 1e-4
#: Largest FIR length (taps) the compensation is designed with: a rate whose filters would need
#: more (the campaign's filter duration at that rate) is refused (resample the measurement).
MAX_TAPS = 2048
#: Largest relative deviation of the FIR from the exact inverse over its band that is accepted.
MAX_DESIGN_ERROR = 0.01
#: Samples per block of the overlap-save convolution (its FFT length).
FFT_BLOCK = 16384
#: Sensor parameters an uncertainty may be stated for, as :class:`WfsSensor` fields.
SENSOR_PARAMETERS = {"sensor_eigenfrequency_hz": "eigenfrequency_hz", "sensor_damping_ratio": "damping_ratio"}


class TyreAlternative(NamedTuple):
    """An identification beside the chosen one whose compensation the band's model-form part holds:
    another amplitude's (``linear_fit`` False), or the chosen amplitude's model fitted without the
    rubber terms the chosen fit has (``linear_fit`` True)."""

    label: str
    model: TyreModel
    tyre: Tyre
    rubber: RubberTerms
    linear_fit: bool = False


@dataclass(frozen=True)
class CompensationBasis:
    """What the compensation of a measurement rests on, whatever its sample rate.

    ``model``, ``tyre``, ``rubber``, ``sensor``: the identification chosen (``label`` says which:
    pressure and amplitude); ``parameters`` and ``covariance``: the uncertain parameters (names of
    :class:`Tyre` or :class:`RubberTerms` fields, ``wheel_mass_kg``, or :data:`SENSOR_PARAMETERS`)
    and their covariance in their units; ``alternatives``: the identifications
    (:class:`TyreAlternative`) whose spread is the tyre's amplitude and rate dependence (the other
    amplitudes', the chosen model fitted without rubber terms); ``accelerometer_delay_s``: the hub
    acceleration's lag the filters undo; ``noise_wfs_n`` and ``noise_accel_m_s2``: the sensors'
    white noise (rms per sample); ``band_hz``: the filters' design band;
    ``filter_s`` and ``latency_s``: their length and latency in time; ``valid_band_hz``: where the
    campaign verified the compensation (lowest, upper frequency)."""

    label: str
    model: TyreModel
    tyre: Tyre
    rubber: RubberTerms
    sensor: WfsSensor
    parameters: tuple[str, ...]
    covariance: np.ndarray
    alternatives: tuple[TyreAlternative, ...]
    accelerometer_delay_s: float
    noise_wfs_n: float
    noise_accel_m_s2: float
    band_hz: float
    filter_s: float
    latency_s: float
    valid_band_hz: tuple[float, float]

    def with_parameter(self, name: str, value: float) -> tuple[Tyre, RubberTerms, WfsSensor]:
        """The tyre, rubber terms and sensor with parameter ``name`` set to ``value``."""
        if name in SENSOR_PARAMETERS:
            return self.tyre, self.rubber, replace(self.sensor, **{SENSOR_PARAMETERS[name]: value})
        if name in {f.name for f in fields(RubberTerms)}:
            return self.tyre, replace(self.rubber, **{name: value}), self.sensor
        if name in {f.name for f in fields(Tyre)}:
            return replace(self.tyre, **{name: value}), self.rubber, self.sensor
        raise AnalysisInputError(f"no parameter {name!r} of a tyre, its rubber terms or the sensor")

    def value(self, name: str) -> float:
        if name in SENSOR_PARAMETERS:
            return float(getattr(self.sensor, SENSOR_PARAMETERS[name]))
        source = self.rubber if name in {f.name for f in fields(RubberTerms)} else self.tyre
        return float(getattr(source, name))


@dataclass(frozen=True)
class CompensationFilters:
    """The filters of a compensation at one sample rate (see the module docstring).

    ``compensator``: the two FIRs (``taps_wfs``, ``taps_accel``, ``latency_samples``);
    ``sensitivity_wfs`` and ``sensitivity_accel``: one column of taps per parameter of
    ``basis.parameters`` (d taps / d parameter); ``deviation_wfs`` and ``deviation_accel``: one
    column per alternative (its taps less the compensator's); ``noise_variance_n2``: the sensors'
    noise through the filters."""

    basis: CompensationBasis
    compensator: ModelCompensator
    sensitivity_wfs: np.ndarray
    sensitivity_accel: np.ndarray
    deviation_wfs: np.ndarray
    deviation_accel: np.ndarray
    noise_variance_n2: float

    @property
    def fs_hz(self) -> float:
        return self.compensator.fs_hz

    @property
    def latency_samples(self) -> int:
        return self.compensator.latency_samples

    @property
    def n_taps(self) -> int:
        return self.compensator.taps_wfs.size


def _design(
    basis: CompensationBasis,
    fs_hz: float,
    shape: tuple[int, int],
    model: TyreModel,
    parts: tuple[Tyre, RubberTerms, WfsSensor],
) -> ModelCompensator:
    """The compensator of ``model`` with ``parts`` (tyre, rubber terms, sensor) at ``fs_hz`` with
    ``shape`` (taps, latency) and the basis's band and accelerometer lag."""
    n_taps, latency = shape
    tyre, rubber, sensor = parts
    return design_model_compensator(
        model,
        tyre,
        sensor,
        rubber,
        fs_hz=fs_hz,
        band_hz=basis.band_hz,
        n_taps=n_taps,
        latency_samples=latency,
        accelerometer_delay_s=basis.accelerometer_delay_s,
    )


def design_filters(basis: CompensationBasis, fs_hz: float) -> CompensationFilters:
    """The compensation's filters at ``fs_hz``: the campaign's filter length and latency in time.

    AnalysisInputError, naming the rate and what it would need, when the rate cannot serve them:
    the design band (with its roll-off to 1.5x the band) must lie below a third of the rate, the
    filters must fit :data:`MAX_TAPS`, and the design must follow the inverse within
    :data:`MAX_DESIGN_ERROR` over the band."""
    if not fs_hz > 3 * basis.band_hz:
        raise AnalysisInputError(
            f"sample rate {fs_hz:g} Hz cannot carry the compensation's band of {basis.band_hz:g} Hz:"
            f" the filters need a rate above {3 * basis.band_hz:g} Hz (3x the band)"
        )
    n_taps = round(basis.filter_s * fs_hz)
    if n_taps > MAX_TAPS:
        raise AnalysisInputError(
            f"sample rate {fs_hz:g} Hz would need {n_taps} taps for the campaign's {basis.filter_s:g} s"
            f" filters (at most {MAX_TAPS}): resample the measurement to at most"
            f" {MAX_TAPS / basis.filter_s:g} Hz"
        )
    latency = round(basis.latency_s * fs_hz)
    shape = (n_taps, latency)
    comp = _design(basis, fs_hz, shape, basis.model, (basis.tyre, basis.rubber, basis.sensor))
    if comp.design_error > MAX_DESIGN_ERROR:
        raise AnalysisInputError(
            f"at {fs_hz:g} Hz the filters follow the inverse only within {100 * comp.design_error:.3g} %"
            f" over the band (at most {100 * MAX_DESIGN_ERROR:g} %)"
        )
    sens_f, sens_a = np.zeros((n_taps, len(basis.parameters))), np.zeros((n_taps, len(basis.parameters)))
    for j, name in enumerate(basis.parameters):
        value = basis.value(name)
        step = RELATIVE_STEP * abs(value) or RELATIVE_STEP
        up = _design(basis, fs_hz, shape, basis.model, basis.with_parameter(name, value + step))
        down = _design(basis, fs_hz, shape, basis.model, basis.with_parameter(name, value - step))
        sens_f[:, j] = (up.taps_wfs - down.taps_wfs) / (2 * step)
        sens_a[:, j] = (up.taps_accel - down.taps_accel) / (2 * step)
    dev_f, dev_a = np.zeros((n_taps, len(basis.alternatives))), np.zeros((n_taps, len(basis.alternatives)))
    for j, alternative in enumerate(basis.alternatives):
        other = _design(
            basis, fs_hz, shape, alternative.model, (alternative.tyre, alternative.rubber, basis.sensor)
        )
        dev_f[:, j] = other.taps_wfs - comp.taps_wfs
        dev_a[:, j] = other.taps_accel - comp.taps_accel
    noise = basis.noise_wfs_n**2 * np.sum(comp.taps_wfs**2) + basis.noise_accel_m_s2**2 * np.sum(
        comp.taps_accel**2
    )
    return CompensationFilters(basis, comp, sens_f, sens_a, dev_f, dev_a, float(noise))


@dataclass(frozen=True)
class CompensatedBlock:
    """Samples ``start`` to ``start + len(force_n)`` of a compensated record: the contact force
    (N) and its 95 % half-width (N); NaN where the filters' window leaves the record."""

    start: int
    force_n: np.ndarray
    u95_n: np.ndarray


class CompensationStream:
    """All of a compensation's filters applied to a whole record, block by block (overlap-save).

    The filters' columns (the compensator, the sensitivities, the deviations) share one FFT of each
    input block. Output sample ``n`` describes input instant ``n`` (the latency removed), as
    :meth:`ModelCompensator.apply` gives it: the first ``n_taps - 1 - latency`` samples and the last
    ``latency`` are NaN (their window reaches beyond the record)."""

    def __init__(self, filters: CompensationFilters, fft_size: int = FFT_BLOCK) -> None:
        self.filters = filters
        n_taps = filters.n_taps
        self.fft_size = max(fft_size, 4 * n_taps)
        self.hop = self.fft_size - (n_taps - 1)
        comp = filters.compensator
        taps_f = np.column_stack([comp.taps_wfs, filters.sensitivity_wfs, filters.deviation_wfs])
        taps_a = np.column_stack([comp.taps_accel, filters.sensitivity_accel, filters.deviation_accel])
        self._spectra_f = np.fft.rfft(taps_f, self.fft_size, axis=0)
        self._spectra_a = np.fft.rfft(taps_a, self.fft_size, axis=0)
        self._n_parameters = filters.sensitivity_wfs.shape[1]

    def blocks(
        self, f_wfs: Record, a_hub: Record, accelerometer_offset_m_s2: float = 0.0
    ) -> Iterator[CompensatedBlock]:
        """The compensated force of the record ``f_wfs`` (N), ``a_hub`` (m/s^2; less
        ``accelerometer_offset_m_s2``, block by block), in blocks of at most :attr:`hop` samples, in
        order. The records are arrays or records on disk: only each block's window is read."""
        if f_wfs.shape != a_hub.shape or len(f_wfs.shape) != 1:
            raise AnalysisInputError(f"Fz and hub acceleration differ in shape: {f_wfs.shape}, {a_hub.shape}")
        n, n_taps, latency = f_wfs.size, self.filters.n_taps, self.filters.latency_samples
        first_valid = n_taps - 1 - latency
        for start in range(0, n, self.hop):
            stop = min(start + self.hop, n)
            # stream outputs start + latency ... stop + latency describe instants start ... stop
            lo, hi = start + latency - (n_taps - 1), stop + latency
            x_f, x_a = _window(f_wfs, lo, hi), _window(a_hub, lo, hi, accelerometer_offset_m_s2)
            if not (np.all(np.isfinite(x_f)) and np.all(np.isfinite(x_a))):
                raise AnalysisInputError("the measurement holds NaN or infinite samples")
            force, variance = self._convolve(x_f, x_a, hi - lo)
            index = np.arange(start, stop)
            bad = (index < first_valid) | (index >= n - latency)
            force[bad], variance[bad] = np.nan, np.nan
            yield CompensatedBlock(start, force, Z95 * np.sqrt(variance))

    def _convolve(self, x_f: np.ndarray, x_a: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
        """Force and its variance for the inputs ``x_f``, ``x_a`` (the last ``size - n_taps + 1``
        samples are outputs; the first ``n_taps - 1`` are their history)."""
        spectrum = np.fft.rfft(x_f, self.fft_size)[:, None] * self._spectra_f
        spectrum += np.fft.rfft(x_a, self.fft_size)[:, None] * self._spectra_a
        y = np.fft.irfft(spectrum, self.fft_size, axis=0)[self.filters.n_taps - 1 : size]
        p = self._n_parameters
        sens, dev = y[:, 1 : 1 + p], y[:, 1 + p :]
        variance = np.einsum("ij,ij->i", sens @ self.filters.basis.covariance, sens)  # s^T C s per sample
        if dev.shape[1]:  # the largest deviation per sample, column by column (a row-wise max is slow)
            variance += functools.reduce(np.maximum, (dev[:, j] ** 2 for j in range(dev.shape[1]))) / 3
        return y[:, 0].copy(), variance + self.filters.noise_variance_n2


def _window(x: Record, lo: int, hi: int, offset: float = 0.0) -> np.ndarray:
    """``x[lo:hi] - offset`` with zeros where the range leaves ``x`` (before its start, after its
    end: no signal there, offset or not)."""
    out = np.zeros(hi - lo)
    a, b = max(lo, 0), min(hi, x.size)
    if b > a:
        out[a - lo : b - lo] = np.asarray(x[a:b], dtype=float) - offset
    return out
