"""Shared fixtures: virtual-lab campaigns generated once per session into the on-demand cache."""

import json
import os

import pytest

from lab_data.cache import campaign_dir
from lab_data.campaign import CampaignConfig, plan_campaign

if os.environ.get("PYTEST_XDIST_WORKER"):
    # the suite runs one worker per core (pyproject addopts): BLAS threads on top would oversubscribe
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


@pytest.fixture(scope="session")
def control_dir():
    return campaign_dir("control")


@pytest.fixture(scope="session")
def control_manifest(control_dir):
    return json.loads((control_dir / "truth.json").read_text())


@pytest.fixture(scope="session")
def plans():
    """Campaign plans (truth + hits, no signals) by scenario, solved lazily."""
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = plan_campaign(CampaignConfig(scenario=name))
        return cache[name]

    return get
