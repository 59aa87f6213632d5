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
from pathlib import Path
from typing import Callable

from ..cache import cache_root, cached_folder, source_hash
from .campaign import LineCampaignConfig, plan_line_campaign, write_line_campaign

__all__ = ["line_campaign_dir", "config_key"]


def _source_hash() -> str:
    """Hash of lab_data.line's and lab_data's sources (the wheelset FE and the line both shape the data)."""
    here = Path(__file__).parent
    return source_hash(here, here.parent)


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
    return cached_folder(target, "truth/truth.json",
                         lambda tmp: write_line_campaign(plan_line_campaign(cfg), tmp, progress=progress,
                                                         workers=workers),
                         f"line campaign {scenario}")
