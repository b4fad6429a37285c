"""Fixtures for debug_gui's browser tests: robots, the GUI as a user starts it, chromium.

* :func:`robot` starts one simulated robot (``python -m humanoid_sim.demo --duration 0
  --namespace NS``) in its own process and session, on a domain the test reserved;
  :func:`fake_robot` a light one (a plain rclpy process publishing callback statistics,
  ``tests/_gui_fake_robot.py``) for tests about the GUI rather than the robot;
  :func:`camera_robot` one with the real ball detector and JPEG compressor behind a drawn
  camera (``tests/_gui_camera_robot.py``), for the image and parameter views.
* :func:`gui` starts ``ros2 run debug_gui debug_gui --port 0 --domains ...`` the way a
  user types it and waits for the URL it prints and for the page to answer.
* the ``browser`` fixture (re-exported by ``tests/conftest.py``) is a headless chromium
  WebDriver, one for the whole session (``chromium_session``), reset between tests (a new
  tab, no cookies or storage, the default size); whatever the test did, its last screen is
  saved under ``tests/artifacts/``.

Waiting is on conditions with deadlines (:func:`wait_for`), never on sleeps.
"""

from __future__ import annotations

import contextlib
import re
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from efficient_comm.testing import ros_env, stop_process_group

ROOT = Path(__file__).resolve().parents[1]
ARTIFACTS = ROOT / "tests" / "artifacts"
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
FAKE_ROBOT = Path(__file__).with_name("_gui_fake_robot.py")
CAMERA_ROBOT = Path(__file__).with_name("_gui_camera_robot.py")
_URL = re.compile(r"at (http://\S+)")
#: The browser's window (width, height), restored between tests.
WINDOW_SIZE = (1600, 1000)


@dataclass
class Process:
    """A program a test started, with the log it writes."""

    proc: subprocess.Popen[bytes]
    log: Path

    def output(self) -> str:
        return self.log.read_text(errors="replace") if self.log.exists() else ""

    def stop(self) -> int:
        return stop_process_group(self.proc)


@dataclass
class RobotProcess(Process):
    domain_id: int
    namespace: str


@dataclass
class GuiProcess(Process):
    #: The URL it printed (with ``?token=``: write access).
    url: str

    @property
    def base_url(self) -> str:
        """The URL without the token: what someone without it opens (read-only)."""
        return self.url.split("?", 1)[0]

    @property
    def token(self) -> str:
        return self.url.split("token=", 1)[1]


@contextmanager
def started(args: Sequence[str | Path], *, env: dict[str, str], log: Path) -> Iterator[Any]:
    log.parent.mkdir(parents=True, exist_ok=True)
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            [str(a) for a in args], env=env, stdout=out, stderr=subprocess.STDOUT,
            start_new_session=True, cwd=log.parent,
        )
    try:
        yield proc
    finally:
        stop_process_group(proc)


def wait_for(
    predicate: Callable[[], Any],
    *,
    timeout_s: float = 30.0,
    what: str = "condition",
    alive: Sequence[Process] = (),
) -> Any:
    """Poll ``predicate`` until it returns something true; fail the test with ``what`` and
    the logs of ``alive`` when the deadline passes or one of them exits."""
    end = time.monotonic() + timeout_s
    while True:
        result = predicate()
        if result:
            return result
        dead = [p for p in alive if p.proc.poll() is not None]
        if dead or time.monotonic() > end:
            logs = "\n".join(f"--- {p.log}:\n{p.output()[-3000:]}" for p in alive)
            reason = f"{[p.proc.args for p in dead]} exited" if dead else f"{timeout_s} s passed"
            pytest.fail(f"waiting for {what}: {reason}\n{logs}")
        time.sleep(0.05)


def wait_for_robots(hub: Any, robots: Sequence[Any], *, alive: Sequence[Process] = (),
                    timeout_s: float = 30.0) -> None:
    """Wait until the Hub sees each of ``robots`` (RobotIds): the test's own, by name.

    Not ``Hub.wait_for_robots(n)``, which returns the first n robots the Hub sees, whichever
    they are. A domain id is reserved for a test, not emptied for it: a participant that
    outlived its test (a process, a daemon, a container left open) is still in the domain
    when the id is reused, and one such robot among the first two made the world view wait
    30 s for poses from a robot that never sends any, while the test's robots ran fine.
    """
    wanted = set(robots)
    wait_for(lambda: wanted <= set(hub.robots()), timeout_s=timeout_s,
             what=f"robots {', '.join(sorted(r.label for r in wanted))} in the Hub",
             alive=alive)


def ready(processes: Sequence[Process], *, timeout_s: float = 30.0) -> None:
    """Wait for each process's ``ready`` line (printed once its publishers exist), so that
    a deadline for data then stands for discovery and delivery, not for start-up."""
    for p in processes:
        wait_for(lambda p=p: "ready" in p.output(), timeout_s=timeout_s,  # type: ignore[misc]
                 what=f"{p.log.name} to be ready", alive=processes)


@contextmanager
def robot(
    tmp_path: Path, *, domain_id: int, namespace: str = "/robot", args: Sequence[str] = ()
) -> Iterator[RobotProcess]:
    """One simulated humanoid (the soccer demo, until stopped) as robot ``namespace``."""
    log = tmp_path / f"robot_{domain_id}{namespace.replace('/', '_')}.log"
    cmd = [sys.executable, "-m", "humanoid_sim.demo", "--duration", "0",
           "--namespace", namespace, *args]
    with started(cmd, env=ros_env(domain_id), log=log) as proc:
        yield RobotProcess(proc=proc, log=log, domain_id=domain_id, namespace=namespace)


@contextmanager
def fake_robot(
    tmp_path: Path, *, domain_id: int, namespace: str = "/robot", period_s: float = 0.5,
    callbacks: int = 3,
) -> Iterator[RobotProcess]:
    """A light robot: a plain rclpy process publishing ExecutorStats for ``namespace``.

    Its callback names carry its namespace (``<ns>/camera``) so two robots' rows differ;
    the last callback's time exceeds its period, to be flagged.
    """
    log = tmp_path / f"fake_{domain_id}{namespace.replace('/', '_')}.log"
    cmd: list[str | Path] = [sys.executable, FAKE_ROBOT, "--namespace", namespace,
                             "--period", str(period_s), "--callbacks", str(callbacks)]
    with started(cmd, env=ros_env(domain_id), log=log) as proc:
        yield RobotProcess(proc=proc, log=log, domain_id=domain_id, namespace=namespace)


@contextmanager
def camera_robot(
    tmp_path: Path, *, domain_id: int, namespace: str = "/robot"
) -> Iterator[RobotProcess]:
    """A light robot with the real camera pipeline as robot ``namespace``: a drawn camera
    (an orange ball on green), humanoid_sim's ball detector and debug_probes' JPEG
    compressor in one container, without the simulation (tests/_gui_camera_robot.py)."""
    log = tmp_path / f"camera_{domain_id}{namespace.replace('/', '_')}.log"
    cmd: list[str | Path] = [sys.executable, CAMERA_ROBOT, "--namespace", namespace]
    with started(cmd, env=ros_env(domain_id), log=log) as proc:
        yield RobotProcess(proc=proc, log=log, domain_id=domain_id, namespace=namespace)


@contextmanager
def gui(
    tmp_path: Path, *, domains: Sequence[int], args: Sequence[str] = (),
    env: dict[str, str] | None = None,
) -> Iterator[GuiProcess]:
    """``ros2 run debug_gui debug_gui --port 0 --domains D,...`` until the page answers."""
    log = tmp_path / "debug_gui.log"
    cmd = ["ros2", "run", "debug_gui", "debug_gui", "--port", "0",
           "--domains", ",".join(map(str, domains)), *args]
    environment = env or ros_env(domains[0])
    with started(cmd, env=environment, log=log) as proc:
        first = Process(proc=proc, log=log)
        match = wait_for(lambda: _URL.search(first.output()), timeout_s=60,
                         what="debug_gui's URL", alive=[first])
        running = GuiProcess(proc=proc, log=log, url=match.group(1))
        wait_for(lambda: _answers(running.base_url), timeout_s=30,
                 what="the page to answer", alive=[running])
        yield running


def _answers(url: str) -> bool:
    try:
        with urllib.request.urlopen(url, timeout=5) as response:
            return int(response.status) == 200
    except OSError:
        return False


def new_browser() -> Any:
    """A headless chromium WebDriver (Debian's chromium and chromedriver)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    if not (CHROMIUM.exists() and CHROMEDRIVER.exists()):
        pytest.fail("chromium and chromedriver missing: run bash scripts/setup_browser.sh")
    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                "--window-size={},{}".format(*WINDOW_SIZE), "--disable-gpu"):
        options.add_argument(arg)
    options.binary_location = str(CHROMIUM)
    return webdriver.Chrome(options=options, service=Service(str(CHROMEDRIVER)))


def screenshot(driver: Any, name: str) -> Path:
    """Save the browser's screen as ``tests/artifacts/<name>.png`` (kept after the test)."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{re.sub(r'[^A-Za-z0-9_.-]+', '_', name)}.png"
    driver.save_screenshot(str(path))
    return path


@pytest.fixture(scope="session")
def chromium_session() -> Iterator[list[Any]]:
    """The session's one chromium (started by the first browser test, replaced if a test
    left it broken): starting chromium and its driver costs seconds a test."""
    holder: list[Any] = []
    try:
        yield holder
    finally:
        for driver in holder:
            with contextlib.suppress(Exception):
                driver.quit()


def fresh_browser(holder: list[Any]) -> Any:
    """The session's chromium (a new one if there is none or it no longer answers)."""
    if holder:
        try:
            holder[0].current_window_handle  # noqa: B018 (answers, or raises)
            return holder[0]
        except Exception:
            with contextlib.suppress(Exception):
                holder[0].quit()
            holder.clear()
    holder.append(new_browser())
    return holder[0]


def reset_browser(driver: Any, holder: list[Any]) -> None:
    """Leave nothing of a test for the next: one new tab at the default size, no cookies,
    no storage of the origins the test visited. A browser that will not reset is quit, so
    the next test gets a new one."""
    try:
        origins = set()
        for handle in driver.window_handles:
            driver.switch_to.window(handle)
            url = str(driver.current_url)
            if url.startswith("http"):
                origins.add("/".join(url.split("/", 3)[:3]))
        driver.switch_to.new_window("tab")
        keep = driver.current_window_handle
        for handle in driver.window_handles:
            if handle != keep:
                driver.switch_to.window(handle)
                driver.close()
        driver.switch_to.window(keep)
        driver.execute_cdp_cmd("Network.clearBrowserCookies", {})
        for origin in origins:
            driver.execute_cdp_cmd("Storage.clearDataForOrigin",
                                   {"origin": origin, "storageTypes": "all"})
        driver.set_window_size(*WINDOW_SIZE)
    except Exception:
        with contextlib.suppress(Exception):
            driver.quit()
        holder.clear()


@pytest.fixture
def browser(request: pytest.FixtureRequest, chromium_session: list[Any]) -> Iterator[Any]:
    """A headless chromium tab (the session's browser, reset after each test); its last
    screen is saved as ``tests/artifacts/<test>.png``."""
    driver = fresh_browser(chromium_session)
    try:
        yield driver
    finally:
        try:
            screenshot(driver, request.node.name)
        except Exception:  # a test that broke the browser: the reset replaces it
            pass
        finally:
            reset_browser(driver, chromium_session)


def reload(driver: Any, *, alive: Sequence[Process] = (), timeout_s: float = 60.0) -> None:
    """Reload the page as NiceGUI does when its handshake fails (``location.reload()``) and
    wait until the document is a new one.

    Not WebDriver's ``refresh()``: chromedriver blocks in it until the new page has loaded
    completely, and on a loaded machine it once stayed there for pytest's whole timeout
    (120 s), where the test's own waits, with deadlines and the server's log on failure,
    are the ones that should judge the page. The old document's marker going away is what
    tells the new document from the old one, whose text the waits would otherwise read.
    """
    driver.execute_script("window.__before_reload = true; location.reload();")
    wait_for(lambda: driver.execute_script("return window.__before_reload !== true;"),
             timeout_s=timeout_s, what="the reloaded page", alive=alive)


def page_text(driver: Any) -> str:
    from selenium.webdriver.common.by import By

    try:
        return str(driver.find_element(By.TAG_NAME, "body").text)
    except Exception:  # the page is being replaced
        return ""


def wait_for_text(
    driver: Any, text: str | re.Pattern[str], *, timeout_s: float = 30.0,
    alive: Sequence[Process] = (),
) -> str:
    """Wait until the page shows ``text`` (a string or a pattern); returns the page text."""
    def shown() -> str:
        body = page_text(driver)
        found = text.search(body) if isinstance(text, re.Pattern) else text in body
        return body if found else ""

    return str(wait_for(shown, timeout_s=timeout_s, what=f"the page to show {text!r}",
                        alive=alive))


def by_testid(driver: Any, testid: str) -> Any:
    """The element NiceGUI rendered with ``.props('data-testid=...')``."""
    from selenium.webdriver.common.by import By

    return driver.find_element(By.CSS_SELECTOR, f'[data-testid="{testid}"]')


def text_of(driver: Any, testid: str) -> str:
    try:
        return str(by_testid(driver, testid).text)
    except Exception:
        return ""


def click(driver: Any, testid: str) -> None:
    by_testid(driver, testid).click()


def click_cell(driver: Any, testid: str, text: str, *, alive: Any = (),
               timeout_s: float = 30.0) -> None:
    """Click the table cell showing ``text`` in the element ``testid``, once it is there.

    Found again on every try: a table re-rendered between finding a cell and clicking it
    (a new rate, a robot arriving) leaves the element found stale."""
    from selenium.common.exceptions import StaleElementReferenceException
    from selenium.webdriver.common.by import By

    def clicked() -> bool:
        try:
            for td in driver.find_elements(By.CSS_SELECTOR, f'[data-testid="{testid}"] td'):
                if td.text == text:
                    td.click()
                    return True
        except StaleElementReferenceException:
            pass
        return False

    wait_for(clicked, what=f"the cell {text!r} of {testid} clicked", alive=alive,
             timeout_s=timeout_s)


def choose(driver: Any, testid: str, option: str, *, timeout_s: float = 10.0) -> None:
    """Pick ``option`` (its text) in the NiceGUI select ``testid``."""
    from selenium.webdriver.common.by import By

    opened = [time.monotonic()]
    by_testid(driver, testid).click()

    def item() -> Any:
        for element in driver.find_elements(By.CSS_SELECTOR, ".q-menu .q-item"):
            try:
                if element.text.strip() == option:
                    return element
            except Exception:  # re-rendered meanwhile
                continue
        return None

    def picked() -> bool:
        # The menu is re-rendered when a robot appears: an option found a moment ago may be
        # gone by the click, so find it again and click that one.
        from selenium.common.exceptions import StaleElementReferenceException

        element = item()
        if element is None:
            # A menu re-rendered while open may close: with no menu for a second after the
            # last click, open it again (a full run once waited 10 s before a closed menu).
            if (not driver.find_elements(By.CSS_SELECTOR, ".q-menu")
                    and time.monotonic() - opened[0] > 1.0):
                opened[0] = time.monotonic()
                with contextlib.suppress(Exception):  # re-rendered meanwhile: next round
                    by_testid(driver, testid).click()
            return False
        try:
            element.click()
        except StaleElementReferenceException:
            return False
        return True

    wait_for(picked, timeout_s=timeout_s, what=f"option {option!r} of {testid}")


def present(driver: Any, testid: str) -> bool:
    from selenium.webdriver.common.by import By

    return bool(driver.find_elements(By.CSS_SELECTOR, f'[data-testid="{testid}"]'))
