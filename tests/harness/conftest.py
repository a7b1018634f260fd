from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))  # the test-method plugin, importable by name in workers too
from harness_test_methods import make_scene  # noqa: E402


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two tiny scenes with query and lighting splits."""
    root = tmp_path_factory.mktemp("data")
    make_scene(root, "sA", splits=("query", "query_light1"), seed=1)
    make_scene(root, "sB", splits=("query", "query_light1"), seed=2)
    return root
