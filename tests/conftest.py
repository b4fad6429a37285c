"""Fixtures shared by the top-level suites: the browser of debug_gui's tests (tests/_gui.py)."""

from ._gui import browser as browser
from ._gui import chromium_session as chromium_session
