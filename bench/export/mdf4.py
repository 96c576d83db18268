"""A campaign's recorded channels as one ASAM MDF 4 file (written by asammdf).

Each run is one channel group: a master channel ``time`` (s from the run's first sample, at the
run's sample rate) and every channel the run recorded, under its name in the campaign file, with
its values as recorded (float32 loads and aux inputs, uint32 counters, uint16 status bits), its
unit, and its description and role in the channel's comment. The group's comment holds what the
run was: kind, status and why, start and end, tyre pressure, amplitudes, the conditions and the
step, and its done points. The file's header comment holds the campaign: the software that wrote
it, its sequence, and the test's metadata (``METADATA_FIELDS``) as named properties, which MDF
readers show as the measurement's properties.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, tostring

import numpy as np

from bench.export.common import done_points, output_file, run_description
from bench.store import CampaignFile, RunView

#: The MDF version written (4.10: read by every current MDF 4 tool).
MDF_VERSION = "4.10"
#: The suffix asammdf gives every file it writes.
MDF_SUFFIX = ".mf4"


def comment_block(tag: str, text: str, properties: dict[str, str], names: tuple[str, ...] = ()) -> str:
    """An MDF 4 comment block (escaped as XML): ``<tag><TX>text</TX>``, the block's ``names`` (a
    channel group's) and ``<common_properties>`` with one ``<e name=...>`` per property."""
    root = Element(tag)
    SubElement(root, "TX").text = text
    if names:
        block_names = SubElement(root, "names")
        for name in names:
            SubElement(block_names, "name").text = name
    common = SubElement(root, "common_properties")
    for name, value in properties.items():
        SubElement(common, "e", name=name).text = value
    return tostring(root, encoding="unicode")


def header_comment(campaign: CampaignFile) -> str:
    """The file's header comment: the campaign and its metadata as properties."""
    properties = {
        "software_version": campaign.software_version,
        "created": campaign.created,
        "sequence_name": campaign.sequence_name,
        "config_name": campaign.config_name,
        **campaign.metadata,
    }
    return comment_block("HDcomment", f"wfs-bench campaign {campaign.path.name}", properties)


def group_comment(run: RunView) -> str:
    """A run's channel-group comment: what the run was, as properties and as ``name: value`` lines
    of its text (readers that show only the text see them too), then its done points (index,
    frequency, amplitude, samples of the point and of its hold); the run id is the group's name."""
    description = run_description(run)
    lines = [f"{name}: {value}" for name, value in description.items()]
    lines.append("done points:")
    lines += [
        f"point {p.index}: {p.freq_hz:g} Hz {p.amplitude_mm:g} mm, samples {p.start_sample}-{p.end_sample},"
        f" hold {p.hold_start_sample}-{p.hold_end_sample}"
        for p in done_points(run)
    ]
    return comment_block("CGcomment", "\n".join(lines), description, names=(run.run_id,))


def _channel_comment(description: str, role: str | None) -> str:
    return f"{description} (role: {role})" if role else description


def write_mdf4(campaign: CampaignFile, runs: tuple[RunView, ...], out: Path) -> None:
    """Write ``runs`` of ``campaign`` to a new MDF 4 file ``out`` (refused if it exists)."""
    from asammdf import MDF, Signal  # a second or more to import: only when exporting

    mdf = MDF(version=MDF_VERSION)
    try:
        mdf.header.start_time = created_time(campaign.created)
        mdf.header.comment = header_comment(campaign)
        for run in runs:
            time_s = np.arange(run.n_samples, dtype=np.float64) / run.sample_rate_hz
            signals = [
                Signal(
                    samples=np.asarray(run.channels[spec.name]),
                    timestamps=time_s,
                    name=spec.name,
                    unit=spec.unit,
                    comment=_channel_comment(spec.description, spec.role.value if spec.role else None),
                )
                for spec in run.channel_specs
            ]
            mdf.append(signals, comment=group_comment(run), common_timebase=True)
        with output_file(out, suffix=MDF_SUFFIX) as temporary:
            mdf.save(temporary, compression=0)
    finally:
        mdf.close()


def created_time(text: str) -> datetime:
    """The campaign's creation instant (ISO 8601; the Unix epoch if it cannot be read)."""
    try:
        created = datetime.fromisoformat(text)
    except ValueError:
        return datetime.fromtimestamp(0, UTC)
    return created if created.tzinfo else created.replace(tzinfo=UTC)
