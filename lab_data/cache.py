"""On-demand cache of virtual-lab campaigns, outside the source tree.

A campaign is about 80 MB of UFF files, so it is generated when first asked
for and kept under ``$RAILMODAL_CACHE`` (default ``~/.cache/railmodal``) in a
folder named after the scenario and a hash of the campaign configuration and
of the virtual lab's source code: changing either gives a fresh campaign.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import tempfile
from dataclasses import asdict
from pathlib import Path
from typing import Callable

from .campaign import CampaignConfig, plan_campaign, write_campaign
from .designs import get_design

__all__ = ["cache_root", "campaign_dir", "cached_folder", "source_hash"]

log = logging.getLogger(__name__)


def cache_root() -> Path:
    """The cache folder: ``$RAILMODAL_CACHE`` or ``~/.cache/railmodal``."""
    return Path(os.environ.get("RAILMODAL_CACHE", Path.home() / ".cache" / "railmodal"))


def source_hash(*folders: Path) -> str:
    """Short hash of the ``*.py`` sources of ``folders`` (in that order): the code that shapes cached data."""
    h = hashlib.sha256()
    for folder in folders:
        for f in sorted(Path(folder).glob("*.py")):
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:12]


def cached_folder(target: Path, complete: str, write: Callable[[Path], object], what: str) -> Path:
    """``target``, written by ``write(folder)`` first unless ``target / complete`` exists.

    ``write`` fills a temporary sibling that is renamed to ``target``, so a crash never leaves a half folder
    behind and two processes asking for the same folder at once both get the complete one (the later rename
    fails and the first one's result is used).
    """
    if (target / complete).exists():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
    try:
        write(tmp)
        try:
            tmp.rename(target)
        except OSError:
            # another process finished the same folder first
            if not (target / complete).exists():
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    log.info("%s cached in %s", what, target)
    return target


def campaign_dir(scenario: str = "control", design: str = "default", **config) -> Path:
    """Folder holding the campaign of ``scenario``, generating it first if needed.

    Parameters
    ----------
    scenario : str
    design : str
        The wheelset design (:data:`lab_data.designs.DESIGNS`); part of the cache key when not the default.
    **config
        Further :class:`~lab_data.campaign.CampaignConfig` fields, e.g.
        ``fe_export_hz=2000.0, fe_style="beam"``; every field, the export
        style included, is part of the cache key.

    Returns
    -------
    Path
        A folder with ``fe_design.uff``, ``fe_design.pch``, ``<setup>.uff``,
        ``<setup>_channels.csv``, ``points.csv`` and ``truth.json``.
    """
    cfg = CampaignConfig(scenario=scenario, **config)
    params = get_design(design)
    key = hashlib.sha256(json.dumps(asdict(cfg), sort_keys=True).encode()).hexdigest()[:12]
    name = scenario if design == "default" else f"{design}-{scenario}"
    target = cache_root() / "lab" / f"{name}-{key}-{source_hash(Path(__file__).parent)}"
    return cached_folder(target, "truth.json", lambda tmp: write_campaign(plan_campaign(cfg, params), tmp),
                         f"campaign {name}")
