"""The monitoring store: every run's and every day's results in a partitioned Parquet dataset.

Layout (Hive partitioning, which pandas/pyarrow, DuckDB and Dask read
directly, without glue code)::

    STORE/
      store.json                                  format and version of the store
      <table>/line=<line>/section=<section>/date=<YYYY-MM-DD>/<key>__<model>.parquet
      references/line=<line>/date=<date>/<model>.parquet   the day's alignment reference

Tables (:data:`TABLES`): ``runs`` (one row per run and section: header, QC,
speed, alignment verdict), ``windows`` (band peak-to-peak per chainage window,
wheelset and rail), ``variants`` (the same from the perturbed and shifted-
sensor models, thesis §4.3.4–4.3.5), ``spectra`` (EN 15610 levels per stretch),
``alignment`` (pieces of every run's chainage correction), ``failures`` (runs
that could not be processed, section ``none``), ``days`` (energy averages
and confidence intervals per window), ``day_sections`` (per section, rail
and band). Every row carries ``model_hash`` (SHA-256 of the model file, first
16 hex digits), ``model_file`` and ``toolkit_version``; the partition
columns ``line``, ``section`` and ``date`` come from the folder names.

**Atomic, idempotent, concurrent writes.** A run's rows go to one file per
partition, named after the run and the model (``<run_id>__<model_hash>``):
re-processing the run with the same model *replaces* those files, a new
model writes files beside them (both versions side by side). Each file is
written to a hidden temporary name in its partition folder (``.<name>.tmp-…``,
ignored by every reader: pyarrow skips names starting with ``.``, and the
suffix is not ``.parquet``) and renamed over the final name with
:func:`os.replace` (atomic on POSIX): a reader sees the old file or the new
one, never half a file. Writers hold an exclusive :func:`fcntl.flock` on
``STORE/.lock`` while they rename, remove stale files (a run whose rows moved
to other sections) and clean temporary files left by a writer that died; two
processes writing at once therefore serialise their updates and lose
nothing. A crash between two partitions of one run leaves that run's old
rows in the partitions not yet replaced (never a partial file, never a
duplicate); ingesting the run again completes it.

**One run per file name.** Because a run's files are named after its run
id, a *different* run whose id is the same (a logger that numbers its runs
from R001 every day) or maps to the same file name (``T12/run 5`` and
``T12_run_5``, :func:`safe_name`) would replace the first one's rows in
every section and on every day. A run's writer therefore states the run
(:meth:`MonitoringStore.write`'s ``run``); under the lock, before anything
is written, the runs already stored under that name are compared with it
(:func:`same_run`) and a different run is refused with
:class:`RunIdCollision`, naming both files.
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import hashlib
import json
import logging
import os
import re
import uuid
from pathlib import Path
from typing import Iterable, Iterator, Mapping

import pandas as pd
import pyarrow as pa
import pyarrow.dataset as pads
import pyarrow.parquet as pq

from estimator.monitoring.errors import StoreError

__all__ = ["MonitoringStore", "TABLES", "RUN_TABLES", "DAY_TABLES", "safe_name", "STORE_FORMAT", "STORE_VERSION",
           "RunIdCollision", "RUN_IDENTITY", "UNKNOWN_DATE", "same_run", "collision_message"]

log = logging.getLogger("estimator")

STORE_FORMAT = "railmodal-monitoring-store"
STORE_VERSION = 1
RUN_TABLES = ("runs", "windows", "variants", "spectra", "alignment", "failures")
DAY_TABLES = ("days", "day_sections")
TABLES = RUN_TABLES + DAY_TABLES
PARTITIONS = ("line", "section", "date")
_SAFE = re.compile(r"[^A-Za-z0-9._+-]")
_DATE = re.compile(r"^(\d{4}-\d{2}-\d{2}|unknown)$")


def safe_name(text) -> str:
    """A partition value or file-name part: letters, digits and ``._+-`` (anything else becomes ``_``)."""
    s = _SAFE.sub("_", str(text).strip())
    if not s or s in (".", ".."):
        raise StoreError(f"{text!r} cannot name a partition or a file")
    return s


# --------------------------------------------------------------------------- run identity
#: what identifies a run in the store (columns of ``runs``; ``failures`` has all but ``train`` and ``bogie``)
RUN_IDENTITY = ("run_id", "date", "source", "train", "bogie")
#: the date of a run whose header could not be read (failures only)
UNKNOWN_DATE = "unknown"


def calendar_date(text: str, unknown_ok: bool = False) -> bool:
    """``YYYY-MM-DD`` naming a day of the calendar (2024-02-30 has the form and is none: stored, it would break
    every later reading of the days), or with ``unknown_ok`` :data:`UNKNOWN_DATE` (a failure's partition)."""
    if not _DATE.match(text):
        return False
    if text == UNKNOWN_DATE:
        return unknown_ok
    try:
        datetime.date.fromisoformat(text)
    except ValueError:
        return False
    return True


class RunIdCollision(StoreError):
    """A run refused because a different run is stored (or ingested) under the same file name.

    Attributes
    ----------
    source, other_source : str
        The refused run's file and the file of the run that holds the name.
    """

    def __init__(self, message: str, source: str = "", other_source: str = "") -> None:
        super().__init__(message)
        self.source = source
        self.other_source = other_source


def _text(value) -> str:
    # identities read back from Parquet carry None/NaN where a column is absent from some files
    return "" if value is None or (isinstance(value, float) and value != value) else str(value)


def _same_file(a: str, b: str) -> bool:
    if a == b:
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


_HASHES: dict[tuple, str] = {}


def _content_hash(path: str) -> str:
    """SHA-256 of a file, remembered per (path, size, modification time): the pre-check and the write both ask."""
    st = os.stat(path)
    key = (os.path.realpath(path), st.st_size, st.st_mtime_ns)
    if key not in _HASHES:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        if len(_HASHES) > 256:
            _HASHES.clear()
        _HASHES[key] = h.hexdigest()
    return _HASHES[key]


def _difference(stored: Mapping, new: Mapping) -> str:
    """Why two runs under one file name are different runs; "" when they are the same run."""
    if _text(stored.get("run_id")) != _text(new.get("run_id")):
        return "different run ids"
    # the header's train and bogie, where both runs record them, tell two loggers' runs of one day apart
    for k in ("train", "bogie"):
        a, b = _text(stored.get(k)), _text(new.get(k))
        if a and b and a != b:
            return f"{k} {a!r} there, {b!r} here"
    d0, d1 = _text(stored.get("date")), _text(new.get("date"))
    dated = d0 not in ("", UNKNOWN_DATE) and d1 not in ("", UNKNOWN_DATE)
    if dated and d0 != d1:
        # even from the same path: a logger that rewrites one file every day; the stored day's recording then
        # survives only in the store, and replacing its rows would lose it
        return "different dates"
    s0, s1 = _text(stored.get("source")), _text(new.get("source"))
    if _same_file(s0, s1):
        return ""
    # another path on the same day (or a header that could not be read): a moved or copied file, or another
    # recording that reuses the id (a logger restarted within the day). Only the stored run's file can tell;
    # when it is gone, the run was moved.
    if not s0 or not os.path.isfile(s0) or not os.path.isfile(s1):
        return ""
    try:
        return "" if _content_hash(s0) == _content_hash(s1) else "the two files differ"
    except OSError:
        return ""


def same_run(stored: Mapping, new: Mapping) -> bool:
    """Whether two runs stored under the same file name are one run (re-processing replaces its rows).

    A run is identified by its run id and survey date (not by its file's path, which changes when the archive
    is moved, nor by a hash of the file, which the store does not record): the same ``run_id`` (exactly, not
    only the same :func:`safe_name`) and the same ``date``, and the same ``train`` and ``bogie`` where both
    record them. Within that, two different paths are one run when their contents are equal or the stored
    run's file no longer exists (it was moved). A run whose header could not be read (date ``unknown`` on
    either side) is matched by its file alone: the same path, an identical copy, or the stored file gone.

    Parameters
    ----------
    stored, new : mapping
        :data:`RUN_IDENTITY` of the stored run and of the run to write (missing keys are unknown).

    Returns
    -------
    bool

    Notes
    -----
    Two dates are two runs even from the same path (a logger that rewrites one file every day: the stored day
    survives only in the store). A run whose header date was corrected therefore needs a new run id, or its
    old files (``<run id>__*.parquet`` under the old date) removed from the store first.
    """
    return not _difference(stored, new)


def collision_message(new: Mapping, stored: Mapping, where: str = "in the store") -> str:
    """The refusal of ``new`` because ``stored`` (a different run, :func:`same_run`) has its file name."""
    rid, other = _text(new.get("run_id")), _text(stored.get("run_id"))
    src, other_src = _text(new.get("source")) or "run", _text(stored.get("source")) or "a run"
    date, other_date = _text(new.get("date")) or UNKNOWN_DATE, _text(stored.get("date")) or UNKNOWN_DATE
    if rid == other:
        what = f"is also the run_id of {other_src} (date {other_date})"
    else:
        what = (f"is stored under the same file name {safe_name(rid)!r} as run_id {other!r} of {other_src} "
                f"(date {other_date}; characters other than letters, digits and ._+- become _)")
    why = _difference(stored, new)
    why = "" if why in ("", "different run ids", "different dates") else f"; {why}"  # the rest says those
    return (f"{src}: run_id {rid!r} (date {date}) {what} {where}{why}; run ids must be unique per line — "
            "rename the run or give it a unique run_id in its header")


class MonitoringStore:
    """A monitoring store folder (module docstring); created on first write.

    Parameters
    ----------
    root : str or Path
        The store folder.
    """

    def __init__(self, root) -> None:
        self.root = Path(root)
        #: (file, size, mtime) of the files :meth:`verify` passed: a second check (reprocess, then its ingest)
        #: reads only the footers of files written or changed since
        self._verified: set[tuple[Path, int, int]] = set()
        if self.root.exists() and not self.root.is_dir():
            raise StoreError(f"store {self.root} is a file, not a folder")
        meta = self.root / "store.json"
        if meta.exists():
            try:
                d = json.loads(meta.read_text())
            except ValueError:
                raise StoreError(f"{meta}: not a JSON store description") from None
            if d.get("format") != STORE_FORMAT:
                raise StoreError(f"{self.root} is not a monitoring store ({meta} says format {d.get('format')!r}, "
                                 f"expected {STORE_FORMAT!r})")
            if int(d.get("version", 0)) > STORE_VERSION:
                raise StoreError(f"{self.root}: store version {d.get('version')} is newer than this toolkit's "
                                 f"({STORE_VERSION}); update railmodal")
        # another process creating the store holds its lock and may be writing store.json's temporary file
        elif self.root.exists() and any(p.name != ".lock" and not p.name.startswith(".store.json.tmp-")
                                        for p in self.root.iterdir()):
            raise StoreError(f"{self.root} is a non-empty folder without store.json: not a monitoring store "
                             "(give an empty or new folder)")

    # ------------------------------------------------------------------ locking
    @contextlib.contextmanager
    def lock(self) -> Iterator[None]:
        """Exclusive lock of the store (between processes and threads); cleans dead writers' temporary files."""
        self.root.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.root / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            meta = self.root / "store.json"
            if not meta.exists():
                self._write_bytes(meta, json.dumps({"format": STORE_FORMAT, "version": STORE_VERSION}).encode())
            self._clean_temporaries()
            yield
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)

    def _clean_temporaries(self) -> None:
        # called with the lock held: any temporary file now is a dead writer's (live ones hold the lock)
        for p in self.root.rglob(".*.tmp-*"):
            with contextlib.suppress(OSError):
                p.unlink()
                log.info("store %s: removed %s left by an interrupted write", self.root, p)

    @staticmethod
    def _write_bytes(path: Path, data: bytes) -> None:
        tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)

    @staticmethod
    def _write_table(frame: pd.DataFrame, path: Path) -> Path:
        """``frame`` to a temporary file beside ``path`` (fsynced); returns the temporary path."""
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")
        table = pa.Table.from_pandas(frame.reset_index(drop=True), preserve_index=False)
        pq.write_table(table, tmp)
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        return tmp

    # ------------------------------------------------------------------ writing
    def _partition(self, table: str, line: str, section: str, date: str) -> Path:
        return self.root / table / f"line={safe_name(line)}" / f"section={safe_name(section)}" / f"date={date}"

    def _split(self, table: str, frame: pd.DataFrame, line: str) -> dict[Path, pd.DataFrame]:
        missing = [c for c in ("section", "date") if c not in frame.columns]
        if missing:
            raise StoreError(f"rows for table {table!r} lack partition column(s) {missing}")
        out = {}
        for (section, date), g in frame.groupby(["section", "date"], sort=True):
            if not calendar_date(str(date), unknown_ok=True):
                raise StoreError(f"table {table!r}: date must be a YYYY-MM-DD calendar date (or 'unknown' for a "
                                 f"failure), got {date!r}")
            out[self._partition(table, line, str(section), str(date))] = g.drop(
                columns=[c for c in PARTITIONS if c in g.columns])
        return out

    @staticmethod
    def _identities(frame: pd.DataFrame) -> list[dict]:
        cols = [c for c in RUN_IDENTITY if c in frame.columns]
        rows = frame[cols].drop_duplicates() if len(frame) else frame
        return [{k: _text(v) for k, v in r.items()} for r in rows.to_dict("records")]

    def _owners(self, line: str, key: str) -> list[dict]:
        """The runs (and failed runs) stored under the file name of ``key`` on ``line``, in every model version."""
        out = []
        stem = safe_name(key)
        seen = set()
        for t in ("runs", "failures"):
            for f in (self.root / t / f"line={safe_name(line)}").glob(f"section=*/date=*/{stem}__*.parquet"):
                # a glob of "R1__*" also finds run "R1__x"'s files; the model version never holds "__"
                if f.name.rsplit("__", 1)[0] != stem:
                    continue
                # one write puts the same run in every section of a date: one of its files is enough
                if (t, f.parent.name, f.name) in seen:
                    continue
                seen.add((t, f.parent.name, f.name))
                try:
                    names = pq.read_schema(f).names
                    frame = pq.read_table(f, columns=[c for c in RUN_IDENTITY if c in names and c != "date"]
                                          ).to_pandas()
                except (pa.ArrowInvalid, OSError) as exc:
                    raise StoreError(f"{f}: cannot be read ({exc})") from None
                out += self._identities(frame.assign(date=f.parent.name.split("=", 1)[1]))
        return out

    def stored_runs(self, line: str | None = None) -> pd.DataFrame:
        """Who holds each run file name: ``line, key`` (the :func:`safe_name` of the run id) and
        :data:`RUN_IDENTITY`, one row per stored run (and failed run) and identity, every model version."""
        frames = []
        for t, cols in (("runs", RUN_IDENTITY), ("failures", ("run_id", "date", "source"))):
            f = self.read(t, line=line, columns=["line", *cols])
            if len(f):
                frames.append(f)
        if not frames:
            return pd.DataFrame(columns=["line", "key", *RUN_IDENTITY])
        f = pd.concat(frames, ignore_index=True)
        for c in RUN_IDENTITY:
            f[c] = f[c].map(_text) if c in f.columns else ""
        f = f.drop_duplicates().reset_index(drop=True)
        return f.assign(key=f["run_id"].map(safe_name))[["line", "key", *RUN_IDENTITY]]

    def write(self, line: str, key: str, model_hash: str, tables: Mapping[str, pd.DataFrame],
              replace_tables: Iterable[str] | None = None, *, run: Mapping | None = None) -> list[Path]:
        """Write one unit's rows (a run, or a day) atomically per partition, replacing that unit's earlier rows.

        Parameters
        ----------
        line : str
            The line's id (partition).
        key : str
            The unit: a run id, or ``day`` for a day's aggregates.
        model_hash : str
            The model version: files are ``<key>__<model_hash>.parquet``.
        tables : mapping of table name → DataFrame
            Rows with ``section`` and ``date`` columns (moved to the partition path).
        replace_tables : iterable of str, optional
            Tables whose earlier files of this unit are removed when not rewritten (default: the tables given,
            plus, for a run, every run table: a re-processed run that now fails loses its old rows).
        run : mapping, optional
            The run being written (:data:`RUN_IDENTITY`; ``run_id`` is ``key``): a *different* run stored under
            the same file name (:func:`same_run`) refuses the write, before anything is written or removed.

        Returns
        -------
        list of Path
            The files written.

        Raises
        ------
        RunIdCollision
            ``run`` is given and another run holds its file name (the message names both files).
        """
        bad = [t for t in tables if t not in TABLES]
        if bad:
            raise StoreError(f"unknown table(s) {bad}; the store holds {list(TABLES)}")
        name = f"{safe_name(key)}__{safe_name(model_hash)}.parquet"
        plan: dict[Path, pd.DataFrame] = {}
        for t, frame in tables.items():
            if frame is None or len(frame) == 0:
                continue
            for part, rows in self._split(t, frame, line).items():
                plan[part / name] = rows
        scope = set(tables) if replace_tables is None else set(replace_tables)
        temps = {}
        written = []
        with self.lock():
            # checked under the lock: a concurrent ingest of the other run cannot slip in between
            if run is not None:
                for owner in self._owners(line, key):
                    if not same_run(owner, run):
                        raise RunIdCollision(collision_message(run, owner), _text(run.get("source")),
                                             owner.get("source", ""))
            try:
                for path, rows in plan.items():
                    temps[path] = self._write_table(rows, path)
                for path, tmp in temps.items():
                    os.replace(tmp, path)
                    written.append(path)
            finally:
                for tmp in temps.values():
                    with contextlib.suppress(FileNotFoundError):
                        tmp.unlink()
            keep = set(plan)
            for t in scope:
                for old in (self.root / t / f"line={safe_name(line)}").glob(f"section=*/date=*/{name}"):
                    if old not in keep:
                        old.unlink()
                        self._prune(old.parent)
        return written

    def _prune(self, folder: Path) -> None:
        """Remove empty partition folders up to the table folder."""
        with contextlib.suppress(OSError):
            while folder != self.root and folder.parent != self.root and not any(folder.iterdir()):
                folder.rmdir()
                folder = folder.parent

    def write_reference(self, line: str, date: str, model_hash: str, frame: pd.DataFrame, meta: Mapping) -> Path:
        """Store a day's alignment reference (feature signal) atomically."""
        path = self.root / "references" / f"line={safe_name(line)}" / f"date={date}" / f"{safe_name(model_hash)}.parquet"
        table = pa.Table.from_pandas(frame, preserve_index=False)
        table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                               b"reference": json.dumps(dict(meta)).encode()})
        with self.lock():
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")
            pq.write_table(table, tmp)
            os.replace(tmp, path)
        return path

    def read_reference(self, line: str, date: str, model_hash: str) -> tuple[pd.DataFrame, dict] | None:
        path = self.root / "references" / f"line={safe_name(line)}" / f"date={date}" / f"{safe_name(model_hash)}.parquet"
        if not path.exists():
            return None
        t = pq.read_table(path)
        meta = json.loads((t.schema.metadata or {}).get(b"reference", b"{}"))
        return t.to_pandas(), meta

    # ------------------------------------------------------------------ checking
    def verify(self) -> int:
        """Refuse a store holding files it did not write, before any work reads or adds to it.

        Every table file must sit in a ``line=/section=/date=`` partition whose date is a calendar date (or
        ``unknown``), be named ``<key>__<model>.parquet`` (a day table's key is ``day-<date>``), be a readable
        Parquet file with a ``model_hash`` column, and hold rows of the model version its name says (from the
        file's column statistics, without reading its data). A copy, a hand-edited or half-written file, or a
        foreign table would otherwise be read as the store's own rows: averaged into the days, or taken as a
        second model version.

        Returns
        -------
        int
            The number of files checked.

        Raises
        ------
        StoreError
            Naming the first file at fault and why.
        """
        n = 0
        for table in TABLES:
            for f in self.files(table):
                n += 1
                try:
                    stat = f.stat()
                except FileNotFoundError:  # replaced or removed by a concurrent writer since the listing
                    continue
                seen = (f, stat.st_size, stat.st_mtime_ns)
                if seen in self._verified:  # unchanged since this store object last checked it
                    continue
                date = f.parent.name.split("=", 1)[1]
                if not calendar_date(date, unknown_ok=True):
                    raise StoreError(f"{f}: partition date {date!r} is not a calendar date; this file was not "
                                     "written by the store (move it out)")
                m = re.fullmatch(r"(.+)__(.+)\.parquet", f.name)
                if m is None or (table in DAY_TABLES and m.group(1) != f"day-{date}"):
                    raise StoreError(f"{f}: not a name the store writes ({'day-<date>' if table in DAY_TABLES else '<run>'}"
                                     "__<model>.parquet in its date's partition): a copy or a foreign file; move it "
                                     "out of the store")
                try:
                    meta = pq.ParquetFile(f).metadata
                except Exception as exc:  # noqa: BLE001 - pyarrow raises several kinds on a damaged file
                    if not f.exists():  # replaced or removed by a concurrent writer since the listing
                        continue
                    raise StoreError(f"{f}: not a readable Parquet file ({type(exc).__name__}: {exc}); remove it and "
                                     "re-ingest its run") from None
                names = meta.schema.names
                if "model_hash" not in names:
                    raise StoreError(f"{f}: no model_hash column: not a {table!r} table the store wrote")
                k = names.index("model_hash")
                for g in range(meta.num_row_groups):
                    st = meta.row_group(g).column(k).statistics
                    if st is None or not st.has_min_max:
                        continue
                    held = {safe_name(str(st.min)), safe_name(str(st.max))}
                    if held != {m.group(2)}:
                        raise StoreError(f"{f}: its rows are of model version(s) {sorted(held)}, its name says "
                                         f"{m.group(2)!r}: a copy or an edited file; move it out of the store")
                self._verified.add(seen)
        return n

    # ------------------------------------------------------------------ reading
    def files(self, table: str) -> list[Path]:
        if table not in TABLES:
            raise StoreError(f"unknown table {table!r}; the store holds {list(TABLES)}")
        return sorted((self.root / table).glob("line=*/section=*/date=*/*.parquet"))

    def read(self, table: str, *, line: str | None = None, section: str | Iterable[str] | None = None,
             date: str | Iterable[str] | None = None, model_hash: str | None = None,
             columns: list[str] | None = None) -> pd.DataFrame:
        """Rows of one table (partition columns as strings), optionally filtered; an empty frame if none."""
        if table not in TABLES:
            raise StoreError(f"unknown table {table!r}; the store holds {list(TABLES)}")
        folder = self.root / table
        if not folder.exists() or not self.files(table):
            return pd.DataFrame()
        part = pads.partitioning(pa.schema([(p, pa.string()) for p in PARTITIONS]), flavor="hive")
        try:
            ds = pads.dataset(folder, format="parquet", partitioning=part)
        except (pa.ArrowInvalid, OSError) as exc:
            raise StoreError(f"{folder}: the dataset cannot be read ({exc})") from None
        flt = None

        def add(expr):
            nonlocal flt
            flt = expr if flt is None else flt & expr

        if line is not None:
            add(pads.field("line") == safe_name(line))
        for name, value in (("section", section), ("date", date)):
            if value is None:
                continue
            vals = [value] if isinstance(value, str) else list(value)
            add(pads.field(name).isin([safe_name(v) if name == "section" else str(v) for v in vals]))
        if model_hash is not None and "model_hash" in ds.schema.names:
            add(pads.field("model_hash") == model_hash)
        try:
            t = ds.to_table(filter=flt, columns=columns)
        except (pa.ArrowInvalid, OSError) as exc:
            raise StoreError(f"{folder}: the dataset cannot be read ({exc})") from None
        return t.to_pandas()

    def lines(self) -> list[str]:
        return sorted({p.name.split("=", 1)[1] for t in TABLES for p in (self.root / t).glob("line=*")})

    def model_versions(self, line: str | None = None) -> pd.DataFrame:
        """The model versions in the store: ``model_hash, model_file, toolkit_version, runs, first/last date``."""
        runs = self.read("runs", line=line, columns=["run_id", "date", "model_hash", "model_file",
                                                     "toolkit_version", "processed_at"])
        if runs.empty:
            return pd.DataFrame(columns=["model_hash", "model_file", "toolkit_version", "runs", "first_date",
                                         "last_date", "processed_at"])
        g = runs.groupby("model_hash")
        return pd.DataFrame({
            "model_hash": list(g.groups),
            "model_file": g["model_file"].first().to_numpy(),
            "toolkit_version": g["toolkit_version"].first().to_numpy(),
            "runs": g["run_id"].nunique().to_numpy(),
            "first_date": g["date"].min().to_numpy(),
            "last_date": g["date"].max().to_numpy(),
            "processed_at": g["processed_at"].max().to_numpy(),
        }).sort_values("processed_at").reset_index(drop=True)
