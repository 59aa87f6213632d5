"""A run file's header without its samples: what a batch needs to group runs by day before processing them."""

from __future__ import annotations

import json
from pathlib import Path

from estimator.errors import RunFileError
from estimator.io.registry import sniff_format

__all__ = ["read_header"]


def read_header(path) -> dict[str, str]:
    """The run header (``run_id, date, direction, …``) of an MDF 4, Parquet or CSV run file, samples unread.

    ``run_id`` defaults to the file's stem when the header lacks it.

    Raises
    ------
    FileNotFoundError, UnknownFormatError, RunFileError
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"run file {p} does not exist")
    fmt = sniff_format(p)
    if fmt == "mdf4":
        from estimator.io.mdf4 import open_mdf, run_header

        mdf = open_mdf(p)
        try:
            header = run_header(mdf, p)
        finally:
            mdf.close()
    elif fmt == "parquet":
        import pyarrow.parquet as pq

        try:
            meta = pq.read_schema(p).metadata or {}
        except Exception as exc:  # noqa: BLE001 - pyarrow raises several kinds on a damaged file
            raise RunFileError(f"{p}: not a readable Parquet file ({type(exc).__name__}: {exc})") from None
        try:
            header = {str(k): str(v) for k, v in json.loads(meta.get(b"run_header", b"{}")).items()}
        except (ValueError, AttributeError):
            raise RunFileError(f"{p}: the run_header metadata is not a JSON object") from None
    elif fmt == "csv":
        from estimator.io.tabular import read_csv_header

        header, _ = read_csv_header(p)
    else:  # a registered plugin without a header-only reader: read it whole
        from estimator.io.registry import read_raw

        raw, _ = read_raw(p, fmt)
        header = dict(raw.header)
    header = dict(header)
    header.setdefault("run_id", p.stem)
    if not header.get("run_id"):
        header["run_id"] = p.stem
    return header
