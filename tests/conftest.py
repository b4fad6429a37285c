"""Fixtures shared by the top-level suites: the browser of debug_gui's tests (tests/_gui.py),
and a private folder for the ``ros2`` command's graph daemons."""

from collections.abc import Iterator

import pytest

from ._cli import daemons_in_tmp
from ._gui import browser as browser
from ._gui import chromium_session as chromium_session


@pytest.fixture(scope="session", autouse=True)
def _graph_daemons(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Every ``ros2`` command a test runs keeps its graph daemons in a folder of this
    session, and they are stopped when the session ends (none outlives the tests)."""
    with daemons_in_tmp(tmp_path_factory.mktemp("daemons")):
        yield
