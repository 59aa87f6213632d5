"""On-demand cache of virtual-line campaigns, outside the source tree.

A campaign folder is generated when first asked for and kept under
``$RAILMODAL_CACHE/line`` (default ``~/.cache/railmodal/line``) in a folder
named after the scenario, a hash of the campaign configuration and a hash of
the virtual lab's and line's source code: changing either gives a fresh
campaign. Tests use :func:`line_campaign_dir` with short sections, e.g.::

    from lab_data.line.cache import line_campaign_dir
    from lab_data.line.campaign import FIRST_CURVE_SECTION
    folder = line_campaign_dir("nominal", days=1, runs_per_day=2, section=FIRST_CURVE_SECTION)
"""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
import tempfile
from pathlib import Path
from typing import Callable

from ..cache import cache_root
from .campaign import LineCampaignConfig, plan_line_campaign, write_line_campaign

__all__ = ["line_campaign_dir", "config_key"]

log = logging.getLogger(__name__)


def _source_hash() -> str:
    """Hash of lab_data's and lab_data.line's sources (the wheelset FE and the line both shape the data)."""
    h = hashlib.sha256()
    here = Path(__file__).parent
    for f in sorted(here.glob("*.py")) + sorted(here.parent.glob("*.py")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def config_key(config: LineCampaignConfig) -> str:
    """Short hash of a configuration (every field counts)."""
    return hashlib.sha256(json.dumps(config.key_dict(), sort_keys=True).encode()).hexdigest()[:12]


def line_campaign_dir(scenario: str = "nominal", *, progress: Callable[[str], None] | None = None,
                      workers: int | None = None, **config) -> Path:
    """Folder holding the virtual-line campaign of ``scenario``, generating it first if needed.

    Parameters
    ----------
    scenario : str
        A field scenario (:data:`lab_data.line.scenarios.FIELD_SCENARIOS`).
    progress : callable, optional
        Called with a message per step when the campaign has to be generated.
    workers : int, optional
        Parallel runs when generating (default: the local cores); not part of the key.
    **config
        Further :class:`~lab_data.line.campaign.LineCampaignConfig` fields (``days``, ``runs_per_day``,
        ``section``, ``wheelset_scenario``, ``seed``, ...).

    Returns
    -------
    Path
        The campaign folder (``line.json``, ``sensors.csv``, ``runs/``, ``trolley/``, ``truth/``).
    """
    cfg = LineCampaignConfig(scenario=scenario, **config)
    target = cache_root() / "line" / f"{scenario}-{config_key(cfg)}-{_source_hash()}"
    if (target / "truth" / "truth.json").exists():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    # write into a temporary sibling and rename, so a crash never leaves a half campaign behind
    tmp = Path(tempfile.mkdtemp(prefix=f".{scenario}-", dir=target.parent))
    try:
        write_line_campaign(plan_line_campaign(cfg), tmp, progress=progress, workers=workers)
        try:
            tmp.rename(target)
        except OSError:
            # another process finished the same campaign first
            if not (target / "truth" / "truth.json").exists():
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    log.info("line campaign %s cached in %s", scenario, target)
    return target
