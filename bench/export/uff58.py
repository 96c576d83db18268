"""The FRFs a campaign's analysis gives, as universal file format (UFF) dataset 58 records, written
by pyuff, after a dataset 164 stating SI units.

What is written (docs/export.md tells a UFF reader how to take it):

- per tyre pressure and dwell-grid amplitude: F_WFS/Z and F_contact/Z (N/m), the raw ratio
  F_WFS/F_contact and, where the amplitude has a tyre fit, the model-compensated ratio
  (dimensionless), all plate-mass corrected, at the dwell frequencies (uneven abscissa);
- the four-post sweep: F_WFS/Z, F_contact/Z (N/m), a_hub/Z (1/s^2) and the hub-acceleration and
  model-compensated forces over Z, each followed by its coherence; the raw, hub-acceleration and
  model-compensated ratios over the contact force; at the Welch bins (even abscissa);
- every FRF is followed by its standard uncertainty: the same abscissa, real, in the FRF's units
  (``sqrt(E |error|^2)`` of the complex value, as the analysis gives it).

Degrees of freedom: node 1 is the contact patch (the shaker plate or the post: the contact force
and the excitation displacement Z), node 2 the wheel centre (the WFS and the hub accelerometer),
direction +3 (+Z, up; forces positive in compression of the tyre). The entity names tell the
measured force from the compensated ones. The z-axis value is the excitation amplitude (m).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

from bench.analysis.campaign import AnalysisKind, CampaignAnalysis
from bench.analysis.frf import Frf
from bench.analysis.runs import FourPostResult, ShakerAmplitudeResult, ShakerCampaignResult
from bench.export.common import output_file

#: Record 6 function types used.
GENERAL, FRF, COHERENCE = 0, 4, 6
#: Record 8-11 specific data types used.
UNKNOWN, GENERAL_DATA, DISPLACEMENT, REACTION_FORCE, ACCELERATION, EXCITATION_FORCE, FREQUENCY = (
    0,
    1,
    8,
    9,
    12,
    13,
    18,
)
#: Nodes and the direction of every degree of freedom.
CONTACT_NODE, WHEEL_NODE, PLUS_Z = 1, 2, 3
#: Characters of an ID line and of an entity name.
ID_LINE_CHARS, ENTITY_CHARS = 80, 10


@dataclass(frozen=True)
class Quantity:
    """A record 8-11 data characteristic: specific data type, length and force unit exponents,
    axis label and units label."""

    data_type: int
    length_exp: int
    force_exp: int
    label: str
    units: str


@dataclass(frozen=True)
class Dof:
    """A degree of freedom of record 6 and what it measures."""

    entity: str
    node: int
    direction: int
    quantity: Quantity


FORCE = (0, 1)
_WFS = Quantity(REACTION_FORCE, *FORCE, "F_WFS", "N")
#: Each signal an exported FRF relates, as a degree of freedom.
DOFS = {
    "f_wfs": Dof("WFS", WHEEL_NODE, PLUS_Z, _WFS),
    "model_compensated": Dof(
        "WFS+MODEL", WHEEL_NODE, PLUS_Z, Quantity(REACTION_FORCE, *FORCE, "F_WFS+model", "N")
    ),
    "hub_compensated": Dof(
        "WFS+HUB", WHEEL_NODE, PLUS_Z, Quantity(REACTION_FORCE, *FORCE, "F_WFS+m a_hub", "N")
    ),
    "f_contact": Dof("CONTACT", CONTACT_NODE, PLUS_Z, Quantity(EXCITATION_FORCE, *FORCE, "F_contact", "N")),
    "z_base": Dof("BASE", CONTACT_NODE, PLUS_Z, Quantity(DISPLACEMENT, 1, 0, "Z", "m")),
    "a_hub": Dof("HUB", WHEEL_NODE, PLUS_Z, Quantity(ACCELERATION, 1, 0, "a_hub", "m/s^2")),
}
_FREQUENCY = Quantity(FREQUENCY, 0, 0, "frequency", "Hz")
_NONE = Quantity(UNKNOWN, 0, 0, "NONE", "NONE")
_COHERENCE = Quantity(GENERAL_DATA, 0, 0, "coherence", "-")
_AMPLITUDE = Quantity(DISPLACEMENT, 1, 0, "amplitude", "m")


@dataclass(frozen=True)
class UffFunction:
    """One FRF to write: ``what`` it is (ID line 1), its ``response`` over its ``reference`` (keys of
    :data:`DOFS`), the ``case`` (ID line 4: pressure, amplitude,
    bench), the ``runs`` it comes from (ID line 2), the ``frf``, the excitation ``amplitude_m``
    (z-axis) and, for a sweep's FRF over Z, its ``coherence``."""

    what: str
    response: str
    reference: str
    case: str
    runs: str
    frf: Frf
    amplitude_m: float
    coherence: np.ndarray | None = None


def _shaker_functions(pressure_bar: float, result: ShakerCampaignResult, runs: str) -> list[UffFunction]:
    out = []
    amplitudes = [*result.amplitudes.values(), *result.ratios_only.values()]
    for amp in sorted(amplitudes, key=lambda a: a.amplitude_m):
        case = f"shaker dwells, tyre {pressure_bar:g} bar, {amp.label}"
        frfs = amp.frfs
        named = [
            ("F_WFS/Z", "f_wfs", "z_base", frfs.wfs_per_z),
            ("F_contact/Z", "f_contact", "z_base", frfs.contact_per_z),
            ("F_WFS/F_contact raw", "f_wfs", "f_contact", frfs.wfs_per_contact),
        ]
        if isinstance(amp, ShakerAmplitudeResult):
            named.append(
                (
                    "F_WFS model-compensated/F_contact",
                    "model_compensated",
                    "f_contact",
                    amp.compensated_per_contact,
                )
            )
        out += [
            UffFunction(what, rsp, ref, case, runs, frf, amp.amplitude_m) for what, rsp, ref, frf in named
        ]
    return out


def four_post_functions(result: FourPostResult, runs: str) -> list[UffFunction]:
    frfs = result.frfs
    case = f"four-post sweep, {result.label}"
    over_z = [  # (what, response, the sweep estimate it comes from, FRF)
        ("F_WFS/Z", "f_wfs", "f_wfs", frfs.wfs_per_z),
        ("F_contact/Z", "f_contact", "f_plate", frfs.contact_per_z),
        ("a_hub/Z", "a_hub", "a_hub", frfs.accel_per_z),
        ("F_WFS hub-compensated/Z", "hub_compensated", "hub_compensated", frfs.sweeps["hub_compensated"].frf),
        (
            "F_WFS model-compensated/Z",
            "model_compensated",
            "model_compensated",
            frfs.sweeps["model_compensated"].frf,
        ),
    ]
    out = [
        UffFunction(what, rsp, "z_base", case, runs, frf, result.amplitude_m, frfs.sweeps[sweep].coherence)
        for what, rsp, sweep, frf in over_z
    ]
    out += [
        UffFunction(what, rsp, "f_contact", case, runs, frf, result.amplitude_m)
        for what, rsp, frf in (
            ("F_WFS/F_contact raw", "f_wfs", result.wfs_per_contact),
            ("F_WFS hub-compensated/F_contact", "hub_compensated", result.hub_compensated_per_contact),
            ("F_WFS model-compensated/F_contact", "model_compensated", result.model_compensated_per_contact),
        )
    ]
    return out


def campaign_functions(analysis: CampaignAnalysis, run_ids: set[str] | None = None) -> list[UffFunction]:
    """Every FRF of the campaign's analysis, or of the analyses of ``run_ids`` only (a dwell grid
    gives its pressure's amplitudes, a four-post sweep its FRFs)."""
    k = analysis.knowledge
    out = []
    for run in analysis.runs:
        if run_ids is not None and run.run_id not in run_ids:
            continue
        pressure = run.results.get("tyre_pressure_bar")
        if run.name is AnalysisKind.SHAKER and pressure in k.shaker:
            out += _shaker_functions(pressure, k.shaker[pressure], run.run_id)
        elif run.name is AnalysisKind.FOUR_POST and k.four_post is not None:
            out += four_post_functions(k.four_post, run.run_id)
    return out


def _clip(text: str, size: int = ID_LINE_CHARS) -> str:
    return (text[:size] or "NONE").encode("ascii", errors="replace").decode("ascii")


def _characteristics(prefix: str, q: Quantity) -> dict:
    return {
        f"{prefix}_spec_data_type": q.data_type,
        f"{prefix}_len_unit_exp": q.length_exp,
        f"{prefix}_force_unit_exp": q.force_exp,
        f"{prefix}_temp_unit_exp": 0,
        f"{prefix}_axis_lab": q.label,
        f"{prefix}_axis_units_lab": q.units,
    }


def _even(freq_hz: np.ndarray) -> bool:
    step = np.diff(freq_hz)
    return step.size > 0 and bool(np.allclose(step, step[0], rtol=1e-9, atol=0.0))


def _record(
    f: UffFunction,
    func_id: int,
    *,
    func_type: int,
    what: str,
    data: np.ndarray,
    ordinate: Quantity,
    denominator: Quantity,
    header: tuple[str, str],
) -> dict:
    response, reference = DOFS[f.response], DOFS[f.reference]
    return {
        "type": 58,
        "binary": 0,
        "id1": _clip(what),
        "id2": _clip(f"runs {f.runs}"),
        "id3": _clip(header[1]),
        "id4": _clip(f.case),
        "id5": _clip(header[0]),
        "func_type": func_type,
        "func_id": func_id,
        "ver_num": 0,
        "load_case_id": 0,
        "rsp_ent_name": response.entity[:ENTITY_CHARS],
        "rsp_node": response.node,
        "rsp_dir": response.direction,
        "ref_ent_name": reference.entity[:ENTITY_CHARS],
        "ref_node": reference.node,
        "ref_dir": reference.direction,
        "abscissa_spacing": int(_even(f.frf.freq_hz)),
        "z_axis_value": f.amplitude_m,
        **_characteristics("abscissa", _FREQUENCY),
        **_characteristics("ordinate", ordinate),
        **_characteristics("orddenom", denominator),
        **_characteristics("z_axis", _AMPLITUDE),
        "x": np.asarray(f.frf.freq_hz, dtype=float),
        "data": data,
    }


def uff_records(functions: list[UffFunction], header: tuple[str, str]) -> list[dict]:
    """The dataset 58 records of ``functions``: each FRF, its coherence (sweeps over Z) and its
    standard uncertainty. ``header``: what ID lines 5 and 3 say of every record (the campaign and
    its metadata; the date)."""
    records = []
    for f in functions:
        numerator, denominator = DOFS[f.response].quantity, DOFS[f.reference].quantity
        common = {"ordinate": numerator, "denominator": denominator, "header": header}
        records.append(
            _record(f, len(records) + 1, func_type=FRF, what=f.what, data=np.asarray(f.frf.value), **common)
        )
        if f.coherence is not None:
            records.append(
                _record(
                    f,
                    len(records) + 1,
                    func_type=COHERENCE,
                    what=f"coherence of {f.what}",
                    data=np.asarray(f.coherence, dtype=float),
                    ordinate=_COHERENCE,
                    denominator=_NONE,
                    header=header,
                )
            )
        records.append(
            _record(
                f,
                len(records) + 1,
                func_type=GENERAL,
                what=f"standard uncertainty of {f.what}",
                data=np.asarray(f.frf.sigma, dtype=float),
                **common,
            )
        )
    return records


def id_date(created: str) -> str:
    """ID line 3: when the campaign was created, ``DD-MMM-YY HH:MM:SS`` as the format asks."""
    try:
        return datetime.fromisoformat(created).strftime("%d-%b-%y %H:%M:%S").upper()
    except ValueError:
        return "NONE"


def write_uff58(functions: list[UffFunction], header: tuple[str, str], out: Path) -> None:
    """Write the SI units record and ``functions`` to a new UFF file ``out`` (refused if it exists)."""
    import pyuff

    units = pyuff.prepare_164(
        units_code=1, units_description="SI", temp_mode=2, length=1.0, force=1.0, temp=1.0, temp_offset=273.15
    )
    with output_file(out) as temporary:
        uff = pyuff.UFF(str(temporary))
        uff.write_sets([units], mode="overwrite")
        uff.write_sets(uff_records(functions, header), mode="add")
