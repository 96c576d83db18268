"""Post-run analysis: FRF estimation, identification, compensation and valid frequency bands.

Pure functions on arrays and parameter objects (no device, engine or UI imports), usable from a
script or a notebook. The top-level API turns whole recorded runs into typed results, data only
(:mod:`bench.report` renders them as text, JSON, figures and HTML): :func:`analyse_shaker_campaign`,
:func:`analyse_four_post`, :func:`analyse_hammer` and :func:`analyse_free_run` on
:class:`DwellRecord`, :class:`SweepRecord` and :class:`HammerRecord`. Every module has one job:

- :mod:`~bench.analysis.records`: the recorded runs the analysis takes, checked by record.
- :mod:`~bench.analysis.runs`: the top-level API and its result types.
- :mod:`~bench.analysis.campaign`: a campaign's analysis as data (what its runs established).
- :mod:`~bench.analysis.validation`: input checks shared by all estimators (clear errors).
- :mod:`~bench.analysis.frf`: the FRF type, point ratios with uncertainty, the valid band.
- :mod:`~bench.analysis.dwell`: sine-dwell fit of every channel.
- :mod:`~bench.analysis.sweep`: H1 or H2 (chosen from the noise floors) and coherence from a sweep.
- :mod:`~bench.analysis.lsq`: bounded weighted least squares with intervals and 'not determined'.
- :mod:`~bench.analysis.fir`: weighted complex least-squares FIR design and a streaming FIR.
- :mod:`~bench.analysis.plate_mass`: m_comp from the free run, contact-force correction.
- :mod:`~bench.analysis.shaker_models`: closed-form shaker responses of Models 1-3.
- :mod:`~bench.analysis.tyre_fit`: identification of Models 1-3 on shaker FRFs.
- :mod:`~bench.analysis.hammer`: sensor eigenfrequency, damping ratio and stiffness.
- :mod:`~bench.analysis.quarter_car_fit`: quarter car above the sensor from a four-post sweep.
- :mod:`~bench.analysis.compensation`: hub-acceleration and model-based compensation.

The top-level names are loaded when first used, not when the package is imported: the store's
reader needs only :mod:`~bench.analysis.records`, and the commands that merely read a campaign file
(or fail to) should not pay for the estimators and their scipy modules.
"""

import importlib
from typing import TYPE_CHECKING

#: The package's top-level names and the module each is defined in.
_PUBLIC = {
    "AnalysisInputError": "bench.analysis.validation",
    "DwellRecord": "bench.analysis.records",
    "FourPostResult": "bench.analysis.runs",
    "FreeRunResult": "bench.analysis.runs",
    "HammerRecord": "bench.analysis.records",
    "ShakerAmplitudeResult": "bench.analysis.runs",
    "ShakerCampaignResult": "bench.analysis.runs",
    "SweepRecord": "bench.analysis.records",
    "analyse_four_post": "bench.analysis.runs",
    "analyse_free_run": "bench.analysis.runs",
    "analyse_hammer": "bench.analysis.runs",
    "analyse_shaker_campaign": "bench.analysis.runs",
    "nominal_free_run": "bench.analysis.runs",
}
__all__ = [
    "AnalysisInputError",
    "DwellRecord",
    "FourPostResult",
    "FreeRunResult",
    "HammerRecord",
    "ShakerAmplitudeResult",
    "ShakerCampaignResult",
    "SweepRecord",
    "analyse_four_post",
    "analyse_free_run",
    "analyse_hammer",
    "analyse_shaker_campaign",
    "nominal_free_run",
]

if TYPE_CHECKING:
    from bench.analysis.records import DwellRecord, HammerRecord, SweepRecord
    from bench.analysis.runs import (
        FourPostResult,
        FreeRunResult,
        ShakerAmplitudeResult,
        ShakerCampaignResult,
        analyse_four_post,
        analyse_free_run,
        analyse_hammer,
        analyse_shaker_campaign,
        nominal_free_run,
    )
    from bench.analysis.validation import AnalysisInputError


def __getattr__(name: str) -> object:
    if name not in _PUBLIC:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_PUBLIC])
