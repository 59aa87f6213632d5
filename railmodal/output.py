"""Write last: a command's results go to a temporary folder that becomes ``--out`` only when it succeeds.

Usage::

    from railmodal.output import staged_output

    with staged_output(args.out) as tmp:      # tmp: an empty folder beside --out
        ...write every result into tmp...
    # here --out holds the results; on an exception nothing was written to --out

The temporary folder is created in the same parent as ``--out`` (so the final
move is a rename on the same file system, not a copy). On success:

* ``--out`` does not exist: the temporary folder is renamed to it (atomic);
* ``--out`` is an existing folder: each entry of the temporary folder replaces
  the entry of the same name in ``--out`` (a file by ``os.replace``, a
  sub-folder removed first); other entries of ``--out`` are left alone.

On any exception (including ``KeyboardInterrupt``) the temporary folder is
removed and the exception propagates: ``--out`` is exactly as it was.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

__all__ = ["OutputFolderError", "check_output_folder", "staged_output"]


class OutputFolderError(OSError):
    """``--out`` cannot be used: an existing file, or a parent that is not a writable folder."""


def check_output_folder(out, option: str = "--out") -> Path:
    """Raise :class:`OutputFolderError` unless ``out`` can become (or already is) an output folder.

    Returns the path; nothing is created.
    """
    p = Path(out)
    if p.exists() and not p.is_dir():
        raise OutputFolderError(f"{option} {str(p)!r} is an existing file, not a folder; give a folder name "
                                f"(it is created) or remove the file")
    parent = p.resolve().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise OutputFolderError(f"{option} {str(p)!r}: {str(parent)!r} is a file, so the folder cannot be created")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputFolderError(f"{option} {str(p)!r}: the folder {str(parent)!r} is not writable")
    # permission bits do not tell everything (root passes them; a read-only or virtual file system does not take
    # files): a folder made and removed at once is the test that holds, before hours of work
    try:
        os.rmdir(tempfile.mkdtemp(prefix=f".{p.name or 'out'}.probe-", dir=parent))
    except OSError as exc:
        raise OutputFolderError(f"{option} {str(p)!r}: nothing can be written in {str(parent)!r} "
                                f"({exc.strerror or exc})") from None
    return p


@contextlib.contextmanager
def staged_output(out, option: str = "--out") -> Iterator[Path]:
    """A temporary folder beside ``out`` whose content becomes ``out`` when the ``with`` block succeeds.

    Parameters
    ----------
    out : str or os.PathLike
        The final output folder (created if needed, with its parents).
    option : str
        The option's name, for messages.

    Yields
    ------
    Path
        The temporary folder to write every result into. Results written
        there are in ``out`` after the block, under the same relative names.

    Raises
    ------
    OutputFolderError
        ``out`` is an existing file or cannot be created (raised before the
        block runs).
    """
    final = check_output_folder(out, option)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.partial-", dir=final.parent))
    try:
        yield tmp
        if not final.exists():
            try:
                tmp.rename(final)
                return
            except OSError:
                # created meanwhile by someone else: fall through to merging entry by entry
                final.mkdir(parents=True, exist_ok=True)
        for entry in sorted(tmp.iterdir()):
            target = final / entry.name
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            elif target.exists() and entry.is_dir():
                target.unlink()
            os.replace(entry, target)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
