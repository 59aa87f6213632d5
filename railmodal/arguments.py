"""Typed, bounded command-line arguments: ``argparse`` ``type=`` factories and actions.

Every size a command is asked for (points, orders, models) and every physical
number it takes is checked when the command line is parsed, before any work:
a value outside its range stops the command with argparse's usage message
(exit status 2) naming the option, the allowed range and the value received,
e.g. ``argument --df: --df must be a number in [0.01, 100] Hz, got 1e-05
(199901 frequency lines; at most 200000)``.

Factories
---------
:func:`bounded_int`, :func:`bounded_float`
    Numbers within a closed or open range (``nan`` and ``inf`` are refused).
:func:`existing_file`, :func:`existing_folder`
    Input paths that must exist and be of that kind ("--hammer is a folder,
    not a file").
:func:`output_folder`
    An ``--out`` folder: refused when it is an existing file or when its
    parent cannot hold it.
:func:`band_action`
    ``--band LOW HIGH`` with ``lo_min <= LOW < HIGH <= hi_max``.

The factories take the option's name so the message names it even when a
type is reused (argparse adds its own ``argument --x:`` prefix as well).
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

__all__ = ["add_geometry_argument", "iso_date", "bounded_int", "bounded_float", "existing_file", "existing_folder", "output_folder", "band_action",
           "calibration_path", "check_choice_list"]


def _fmt(v: float) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _range_text(lo, hi, lo_open: bool, hi_open: bool, unit: str) -> str:
    left = "(" if lo_open else "["
    right = ")" if hi_open else "]"
    return f"{left}{_fmt(lo)}, {_fmt(hi)}{right}" + (f" {unit}" if unit else "")


def bounded_int(option: str, lo: int, hi: int, *, what: str = "an integer"):
    """``type=`` for an integer in ``[lo, hi]``.

    Parameters
    ----------
    option : str
        The option's name (``"--max-order"``), quoted in the message.
    lo, hi : int
        Inclusive bounds.
    what : str
        How to call the value in the message.
    """

    def parse(text: str) -> int:
        try:
            value = int(str(text).strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} must be {what} in [{lo}, {hi}], got {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{option} must be {what} in [{lo}, {hi}], got {value}")
        return value

    parse.__name__ = f"int in [{lo}, {hi}]"
    return parse


def bounded_float(option: str, lo: float = -math.inf, hi: float = math.inf, *, lo_open: bool = False,
                  hi_open: bool = False, unit: str = "", check=None):
    """``type=`` for a finite float in a range.

    Parameters
    ----------
    option : str
        The option's name, quoted in the message.
    lo, hi : float
        Bounds (infinite for none).
    lo_open, hi_open : bool
        Exclude the bound itself.
    unit : str
        Unit quoted in the message.
    check : callable(float) -> str or None, optional
        A further test; returns a reason (appended to the message) when the
        value is refused.
    """
    rng = _range_text(lo, hi, lo_open, hi_open, unit)

    def parse(text: str) -> float:
        try:
            value = float(str(text).strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} must be a number in {rng}, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{option} must be a finite number in {rng}, got {text!r}")
        below = value <= lo if lo_open else value < lo
        above = value >= hi if hi_open else value > hi
        if below or above:
            raise argparse.ArgumentTypeError(f"{option} must be a number in {rng}, got {value:g}")
        if check is not None:
            reason = check(value)
            if reason:
                raise argparse.ArgumentTypeError(f"{option} = {value:g} is refused: {reason}")
        return value

    parse.__name__ = f"number in {rng}"
    return parse


def existing_file(option: str, role: str):
    """``type=`` for an input file that must exist and be a file (not a folder)."""

    def parse(text: str) -> Path:
        p = Path(text)
        if p.is_dir():
            raise argparse.ArgumentTypeError(f"{option} {text!r} is a folder, not a file; give the {role} file")
        if not p.exists():
            raise argparse.ArgumentTypeError(f"{option}: {role} {text!r} does not exist")
        if not os.access(p, os.R_OK):
            raise argparse.ArgumentTypeError(f"{option}: {role} {text!r} cannot be read (permission denied)")
        return p

    parse.__name__ = "existing file"
    return parse


def existing_folder(option: str, role: str, *, file_ok: bool = False):
    """``type=`` for an input folder that must exist (a file is accepted too when ``file_ok``)."""

    def parse(text: str) -> Path:
        p = Path(text)
        if not p.exists():
            raise argparse.ArgumentTypeError(f"{option}: {role} {text!r} does not exist")
        if p.is_file() and not file_ok:
            raise argparse.ArgumentTypeError(f"{option} {text!r} is a file, not a folder; give the {role} folder")
        return p

    parse.__name__ = "existing folder"
    return parse


def iso_date(option: str):
    """An argparse type: a ``YYYY-MM-DD`` calendar date, returned in that form (2024-13-01 is refused at parsing,
    before any work, rather than found missing after it)."""
    def parse(text: str) -> str:
        import datetime as _dt

        try:
            return _dt.date.fromisoformat(text).isoformat()
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} must be a date YYYY-MM-DD, got {text!r}") from None

    parse.__name__ = "date"
    return parse


def calibration_path(text: str) -> str:
    """``type=`` for ``--calibration``: a calibrated-model folder of ``railmodal field diagnose`` (with
    ``field_calibration.json``) or that JSON file."""
    p = Path(text)
    if not (p / "field_calibration.json").is_file() and not (p.is_file() and p.suffix == ".json"):
        raise argparse.ArgumentTypeError(f"{text} is neither a calibrated-model folder (with field_calibration.json) "
                                         f"nor such a JSON file")
    return str(p)


def output_folder(option: str = "--out"):
    """``type=`` for an output folder: not an existing file, and its nearest existing parent must be a writable folder."""

    def parse(text: str) -> Path:
        if not str(text).strip():
            raise argparse.ArgumentTypeError(f"{option} must name a folder, got an empty string")
        p = Path(text)
        if p.exists() and not p.is_dir():
            raise argparse.ArgumentTypeError(f"{option} {text!r} is an existing file, not a folder; give a folder "
                                             f"name (it is created) or remove the file")
        parent = p.resolve().parent
        while not parent.exists():
            parent = parent.parent
        if not parent.is_dir():
            raise argparse.ArgumentTypeError(f"{option} {text!r}: {str(parent)!r} is a file, so the folder cannot "
                                             f"be created")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise argparse.ArgumentTypeError(f"{option} {text!r}: the folder {str(parent)!r} is not writable")
        return p

    parse.__name__ = "output folder"
    return parse


def band_action(option: str, lo_min: float, hi_max: float, *, unit: str = "Hz", min_ratio: float = 1.0):
    """An ``argparse.Action`` for ``OPTION LOW HIGH`` (``nargs=2``): ``lo_min <= LOW < HIGH <= hi_max``.

    Use with ``type=bounded_float(...)`` or ``type=float``; the pair is
    checked here (a reversed band is refused, naming both values).
    ``min_ratio`` > 1 asks for ``HIGH >= min_ratio * LOW``.
    """

    class BandAction(argparse.Action):
        def __call__(self, parser, namespace, values, option_string=None):
            lo, hi = (float(v) for v in values)
            if not (math.isfinite(lo) and math.isfinite(hi)):
                parser.error(f"argument {option}: {option} LOW HIGH must be finite numbers, got {lo:g} {hi:g}")
            if lo < lo_min or hi > hi_max:
                parser.error(f"argument {option}: {option} LOW HIGH must lie in [{lo_min:g}, {hi_max:g}] {unit}, "
                             f"got {lo:g} {hi:g}")
            if not lo < hi:
                parser.error(f"argument {option}: {option} LOW HIGH needs LOW < HIGH, got {lo:g} {hi:g} "
                             f"(reversed or empty band)")
            if hi < min_ratio * lo:
                parser.error(f"argument {option}: {option} HIGH must be at least {min_ratio:g} x LOW, got {lo:g} "
                             f"{hi:g}")
            setattr(namespace, self.dest, [lo, hi])

    return BandAction


def check_choice_list(parser: argparse.ArgumentParser, option: str, values, limit: int) -> None:
    """Refuse more than ``limit`` repetitions of an ``action="append"`` option (argparse exit status 2)."""
    if values is not None and len(values) > limit:
        parser.error(f"argument {option}: at most {limit} {option} options, got {len(values)}")


def add_geometry_argument(parser) -> None:
    """``--geometry`` and ``--fe-units``: node coordinates and the unit system of an FE export that states neither
    (shared by every command reading an FE)."""
    from fem_import.modes import UNIT_SYSTEMS

    parser.add_argument("--geometry", default=None, type=existing_file("--geometry", "geometry"),
                        help="node coordinates and elements for an FE file without them (a Nastran punch or "
                             ".f06): a UFF with datasets 2411/2412 or a Nastran bulk data file (default: a companion "
                             "file of the same name, .bdf/.dat/.nas/.uff)")
    parser.add_argument("--fe-units", default=None, choices=tuple(UNIT_SYSTEMS),
                        help="unit system of an FE export that does not state it (a Nastran punch, .f06, .op2 or .h5 "
                             "and bulk deck, a UFF without dataset 164, a CalculiX .frd, an ANSYS .rst without /UNITS "
                             "whose materials do not tell), converted to SI: e.g. mm-t-s, the usual Nastran set for "
                             "steel (default: SI as read; a UFF with dataset 164 and an ANSYS /UNITS are converted by "
                             "them)")
