"""Fixtures shared by the navigator's tests."""

import pytest

from swarm_nav.config import CostmapConfig
from swarm_nav.costmap import build_costmap
from tests.swarm_nav.helpers import slim_blockage_map


@pytest.fixture(scope="module")
def costmap():
    """The costmap of the slim_blockage map rasterised from its walls (default settings)."""
    return build_costmap(slim_blockage_map(), CostmapConfig())
