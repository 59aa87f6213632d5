"""Writers of the virtual line's files (the field file contract) and small readers for tests.

* ``line.json`` — the line description (:func:`lab_data.line.geometry.line_dict`);
* ``sensors.csv`` — one row per MDF4 channel (:func:`lab_data.line.sensors.sensor_table`);
* ``runs/<YYYY-MM-DD>/<run_id>.mf4`` — ASAM MDF 4.10 written with asammdf: a
  channel group with the six accelerations at ``fs`` (float32, in g), one with
  encoder speed and odometer position at 100 Hz, one with the balise events
  (one sample per passage, value = the balise's reference chainage); every
  channel with its unit and a comment; the header comment's
  ``<common_properties>`` hold ``run_id, date, direction, orientation, train,
  bogie, line`` and the record's start time is the header's start time;
* ``trolley/<YYYY-MM-DD>.csv`` — ``chainage_m, rail, roughness_um`` like a
  corrugation trolley's export;
* ``truth/truth.json`` + Parquet arrays — only tests read them
  (:func:`read_truth`, :func:`read_true_roughness`).
"""

from __future__ import annotations

import datetime as _dt
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["TRUTH_FORMAT", "TRUTH_VERSION", "write_json", "write_run_mdf", "write_trolley_csv",
           "write_roughness_parquet", "read_truth", "read_true_roughness", "read_run_truth", "header_properties"]

TRUTH_FORMAT = "railmodal-virtual-line-truth"
TRUTH_VERSION = 1


def write_json(obj: dict, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=1, default=_json_default))
    return path


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _hd_comment(description: str, properties: dict[str, str]) -> str:
    root = ET.Element("HDcomment")
    ET.SubElement(root, "TX").text = description
    common = ET.SubElement(root, "common_properties")
    for k, v in properties.items():
        ET.SubElement(common, "e", name=k).text = str(v)
    return ET.tostring(root, encoding="unicode")


def header_properties(mdf) -> dict[str, str]:
    """The ``<common_properties>`` of an MDF4 header comment, parsed from the XML (no private asammdf API)."""
    text = mdf.header.comment
    root = ET.fromstring(text)
    return {e.attrib["name"]: (e.text or "") for e in root.iter("e")}


def write_run_mdf(path: Path, *, start: _dt.datetime, header: dict[str, str], description: str,
                  acc: np.ndarray, fs: float, acc_names: list[str], acc_comments: list[str],
                  odo_t: np.ndarray, speed: np.ndarray, position: np.ndarray, odo_names: tuple[str, str],
                  balise_t: np.ndarray, balise_value: np.ndarray, balise_name: str) -> Path:
    """One run as an MDF 4.10 file (see the module docstring); times in s from the record start."""
    from asammdf import MDF, Signal

    path.parent.mkdir(parents=True, exist_ok=True)
    mdf = MDF(version="4.10")
    mdf.header.start_time = start
    mdf.header.comment = _hd_comment(description, header)
    t = np.arange(acc.shape[1]) / fs
    mdf.append([Signal(acc[i].astype(np.float32), t, name=n, unit="g", comment=c)
                for i, (n, c) in enumerate(zip(acc_names, acc_comments))],
               comment=f"axlebox accelerations, {fs:g} Hz")
    mdf.append([Signal(speed.astype(np.float64), odo_t, name=odo_names[0], unit="m/s",
                       comment="encoder speed (nominal wheel radius)"),
                Signal(position.astype(np.float64), odo_t, name=odo_names[1], unit="m",
                       comment="odometer position: integrated encoder distance, reset at balises")],
               comment="odometry")
    mdf.append([Signal(balise_value.astype(np.float64), balise_t.astype(np.float64), name=balise_name, unit="m",
                       comment="balise passage: reference chainage of the balise")],
               comment="balise events")
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


def write_trolley_csv(path: Path, chainage_m: np.ndarray, roughness_m: np.ndarray, *, rows_per_chunk: int = 100_000
                      ) -> Path:
    """A trolley export: rows per rail (``L`` then ``R``), chainage and roughness in µm with 4 decimals.

    The text is what ``DataFrame.to_csv(float_format="%.4f")`` writes, byte for byte, formatted by ``%`` on a
    chunk of rows at once: pandas formats a ``float_format`` column value by value in Python, 3.5 s of a one-run
    campaign's 15.5 s at the trolley's 1 mm step over 410 m (this way 0.5 s).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    x = np.asarray(chainage_m, float)
    with open(path, "w", newline="") as fh:
        fh.write("chainage_m,rail,roughness_um\n")
        for i, rail in enumerate("LR"):
            um = np.asarray(roughness_m[i], float) * 1e6
            for a in range(0, x.size, rows_per_chunk):
                pairs = np.column_stack([x[a:a + rows_per_chunk], um[a:a + rows_per_chunk]]).ravel()
                text = (f"%.4f,{rail},%.4f\n" * (pairs.size // 2)) % tuple(pairs.tolist())
                fh.write(text.replace("nan", ""))  # pandas writes a missing value as an empty field
    return path


def write_roughness_parquet(path: Path, chainage_m: np.ndarray, roughness_m: np.ndarray) -> Path:
    """True rail roughness on a grid: ``chainage_m`` (float64) and ``L_um``, ``R_um`` (float32)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    df = pd.DataFrame({"chainage_m": chainage_m, "L_um": (roughness_m[0] * 1e6).astype(np.float32),
                       "R_um": (roughness_m[1] * 1e6).astype(np.float32)})
    df.to_parquet(path, index=False, compression="zstd")
    return path


def read_truth(campaign: str | Path) -> dict:
    """The truth manifest of a campaign folder."""
    return json.loads((Path(campaign) / "truth" / "truth.json").read_text())


def read_true_roughness(campaign: str | Path, date: str) -> pd.DataFrame:
    """True rail roughness of ``date``: ``chainage_m, L_um, R_um`` (what a perfect trolley would measure)."""
    return pd.read_parquet(Path(campaign) / "truth" / "rail_roughness" / f"{date}.parquet")


def read_run_truth(campaign: str | Path, run_id: str) -> pd.DataFrame:
    """True bogie chainage and speed against the record's time (``t_s, chainage_m, speed_m_s``)."""
    return pd.read_parquet(Path(campaign) / "truth" / "runs" / f"{run_id}.parquet")
