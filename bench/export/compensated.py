"""A compensated force (the output of ``wfsbench compensate``) exported as a run is: CSV or MDF4
(docs/export.md, *A compensated force*).

- **CSV**, a new folder holding ``<name>.csv`` (the file's name without its suffix): the columns
  ``time_s`` (the measurement's own time, as the file keeps it), ``f_contact_n`` and ``u95_n``, a
  units row under the header, the float32 values as the shortest decimals that read back the same
  (NaN where the filters' window reaches beyond the record).
- **MDF4**, one file: one channel group named after the file, its master channel ``time`` (the
  measurement's time) and the two channels with their units and descriptions; the header comment
  holds what made the force (campaign, measurement, identification, valid band, every assumption)
  as named properties.

Both are written block by block (the memory taken does not grow with the record), into a temporary
beside the output that becomes it once complete; an existing output is never replaced.
"""

from __future__ import annotations

from pathlib import Path

from bench.export.common import output_file, output_folder
from bench.export.csv_files import DELIMITER, TIME_COLUMN
from bench.export.mdf4 import MDF_SUFFIX, MDF_VERSION, comment_block, created_time
from bench.store.compensated import SERIES, CompensatedFile

#: The formats a compensated force is exported in.
COMPENSATED_FORMATS = ("csv", "mdf4")
#: The exported channels: the per-sample datasets but the time.
CHANNELS = tuple(name for name in SERIES if name != "t_s")


def _stem(compensated: CompensatedFile) -> str:
    return compensated.path.name.removesuffix(compensated.path.suffix)


def write_compensated_csv(compensated: CompensatedFile, out: Path) -> Path:
    """The force as ``out/<name>.csv`` in a new folder ``out``; the file's path."""
    with output_folder(out) as folder:
        name = f"{_stem(compensated)}.csv"
        with (folder / name).open("w", encoding="utf-8", newline="\n") as f:
            f.write(DELIMITER.join((TIME_COLUMN, *CHANNELS)) + "\n")
            f.write(DELIMITER.join(SERIES[name][1] for name in SERIES) + "\n")
            for block in compensated.blocks():
                # numpy's str of a float is the shortest decimal that reads back as the same value
                texts = [block[name].astype(str).tolist() for name in SERIES]
                f.write("\n".join(map(DELIMITER.join, zip(*texts, strict=True))) + "\n")
    return out / name


def write_compensated_mdf4(compensated: CompensatedFile, out: Path) -> None:
    """The force as a new MDF 4 file ``out``: one channel group, appended block by block."""
    from asammdf import MDF, Signal  # a second or more to import: only when exporting

    attributes, stem = compensated.attributes, _stem(compensated)
    properties = {key: str(value) for key, value in attributes.items() if key != "assumptions"}
    text = f"wfs-bench compensated force {compensated.path.name}\n{attributes.get('assumptions', '')}"
    mdf = MDF(version=MDF_VERSION)
    try:
        mdf.header.start_time = created_time(str(attributes.get("created", "")))
        mdf.header.comment = comment_block("HDcomment", text, properties)
        group = None
        for block in compensated.blocks():
            if group is None:
                signals = [
                    Signal(block[name], block["t_s"], name=name, unit=unit, comment=description)
                    for name in CHANNELS
                    for _, unit, description in (SERIES[name],)
                ]
                mdf.append(signals, comment=comment_block("CGcomment", stem, {}, names=(stem,)))
                group = len(mdf.groups) - 1
            else:
                mdf.extend(group, [(block["t_s"], None), *((block[name], None) for name in CHANNELS)])
        with output_file(out, suffix=MDF_SUFFIX) as temporary:
            mdf.save(temporary, compression=0)
    finally:
        mdf.close()
