"""Shared fixtures: virtual-lab campaigns generated once per session into the on-demand cache."""

import json

import pytest

from lab_data.cache import campaign_dir
from lab_data.campaign import CampaignConfig, plan_campaign


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
