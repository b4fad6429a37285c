"""How busy the landing page keeps the browser, and how fast it answers a click.

Three light robots (tests/_gui_fake_robot.py: each publishes the statistics of
``--callbacks`` callbacks once a second, as a robot's container does), ``debug_gui`` started
as a user starts it with its default layout (the components view for the whole team: one
table per robot), and headless chromium showing it. Per page policy and run:

* the browser's main-thread busy share: the Chrome DevTools Protocol's
  ``Performance.getMetrics`` ``TaskDuration`` (seconds the renderer's main thread spent in
  tasks) over ``--seconds`` of wall time, and its CPU share (``ThreadTime``: the same
  tasks' CPU seconds; on a loaded machine tasks wait for a core, so busy exceeds CPU);
* click-to-answer: a click on robot 1's "all columns" switch until the table shows the
  extra column (timed in the page, from the click to the DOM change), ``--clicks`` times.

Policies, each its own GUI process, measured in the same run: ``idle`` (the same page with
no robots: what the page costs doing nothing), ``old`` (the table before issue 18: a
``ui.table`` with slot templates, every row re-sent every second,
``DEBUG_GUI_UPDATE_POLICY=every-second``) and ``new`` (the default: changed cells and the
status line only, at most every 2 s, every table's in one render). ``--hogs N`` runs N
busy-looping processes beside it (a loaded machine).
Printed per run and as medians over ``--repeat`` runs, with the ratios old / new.

Run: ``source scripts/env.sh && python bench/gui_page_bench.py --hogs 2``
(``--quick``: one short run, for the smoke test).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from efficient_comm.testing import isolated_domain_id, ros_env  # noqa: E402
from tests._gui import fake_robot, gui, new_browser, wait_for  # noqa: E402

POLICIES = ("idle", "old", "new")
#: Time a click in the page until the table's header shows the "calls" column again.
_CLICK = r"""
const [testid, done] = arguments;
const table = document.querySelector('[data-testid="' + testid + '"]');
const toggle = document.querySelector('[data-testid="' + testid.replace('components-',
    'components-columns-') + '"]');
const has = () => [...table.querySelectorAll('th')].some(th => th.textContent.includes('calls'));
const before = has();
const t0 = performance.now();
const observer = new MutationObserver(() => {
  if (has() !== before) { observer.disconnect(); done(performance.now() - t0); }
});
observer.observe(table, {subtree: true, childList: true, characterData: true});
toggle.click();
setTimeout(() => { observer.disconnect(); done(-1); }, 60000);
"""


def _hogs(count: int) -> list[subprocess.Popen[bytes]]:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(count)]


def measure(tmp: Path, *, policy: str, seconds: float, clicks: int, callbacks: int,
            robots: int) -> dict[str, float]:
    domain = isolated_domain_id()
    env = ros_env(domain)
    if policy == "old":
        env["DEBUG_GUI_UPDATE_POLICY"] = "every-second"
    with ExitStack() as stack:
        procs = [] if policy == "idle" else [
            stack.enter_context(fake_robot(tmp, domain_id=domain, namespace=f"/robot{k}",
                                           period_s=1.0, callbacks=callbacks))
            for k in range(1, robots + 1)]
        server = stack.enter_context(gui(tmp, domains=[domain], env=env))
        browser = new_browser()
        stack.callback(browser.quit)
        browser.set_script_timeout(90)
        browser.get(server.url)
        if procs:
            first = f"components-{domain}:/robot1"
            wait_for(lambda: _rows(browser, robots) >= robots * callbacks, timeout_s=120,
                     what="every robot's rows", alive=[*procs, server])
        else:
            wait_for(lambda: "no robots" in browser.page_source, what="the empty page")
        browser.execute_cdp_cmd("Performance.enable", {})
        (busy0, cpu0), t0 = _task_s(browser), time.monotonic()
        time.sleep(seconds)  # the measurement window, not synchronisation
        (busy1, cpu1), t1 = _task_s(browser), time.monotonic()
        latencies = []
        if procs:
            for _ in range(clicks):
                latencies.append(float(browser.execute_async_script(_CLICK, first)) / 1e3)
    return {"busy_share": (busy1 - busy0) / (t1 - t0),
            "cpu_share": (cpu1 - cpu0) / (t1 - t0),
            "click_s": statistics.median(latencies) if latencies else 0.0,
            "click_max_s": max(latencies) if latencies else 0.0}


def _rows(browser: Any, robots: int) -> int:
    try:
        return int(browser.execute_script(
            "return document.querySelectorAll('[data-testid^=\"components-\"] tbody tr')"
            ".length"))
    except Exception:  # the page is being replaced
        return 0


def _task_s(browser: Any) -> tuple[float, float]:
    """Seconds the renderer's main thread spent in tasks (wall time: what a user waits
    behind) and on the CPU (what the page itself costs; on a loaded machine a task takes
    longer in wall time than on the CPU, as the thread waits for a core)."""
    metrics = {m["name"]: m["value"]
               for m in browser.execute_cdp_cmd("Performance.getMetrics", {})["metrics"]}
    return float(metrics["TaskDuration"]), float(metrics["ThreadTime"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--clicks", type=int, default=5)
    ap.add_argument("--robots", type=int, default=3)
    ap.add_argument("--callbacks", type=int, default=40,
                    help="callbacks per robot (the simulated soccer robot has about 40)")
    ap.add_argument("--hogs", type=int, default=0, help="busy-looping processes beside it")
    ap.add_argument("--quick", action="store_true", help="one run of 3 s (smoke test)")
    ap.add_argument("--out", type=Path, default=None, help="write the records as JSON")
    args = ap.parse_args()
    if args.quick:
        args.repeat, args.seconds, args.clicks = 1, 3.0, 1
    import tempfile

    records: dict[str, list[dict[str, float]]] = {p: [] for p in POLICIES}
    hogs = _hogs(args.hogs)
    try:
        for run in range(args.repeat):
            for policy in POLICIES[run % 3:] + POLICIES[:run % 3]:  # rotate the order
                with tempfile.TemporaryDirectory(prefix="gui_page_bench_") as tmp:
                    rec = measure(Path(tmp), policy=policy, seconds=args.seconds,
                                  clicks=args.clicks, callbacks=args.callbacks,
                                  robots=args.robots)
                records[policy].append(rec)
                print(f"run {run + 1} {policy}: main thread {100 * rec['busy_share']:.1f} % "
                      f"busy ({100 * rec['cpu_share']:.1f} % on the CPU), click answered in "
                      f"{rec['click_s']:.3f} s (max "
                      f"{rec['click_max_s']:.3f} s); load {os.getloadavg()[0]:.1f}",
                      flush=True)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    med = {p: {k: statistics.median(r[k] for r in recs) for k in recs[0]}
           for p, recs in records.items()}
    new, old, idle = med["new"], med["old"], med["idle"]
    print(f"median of {args.repeat} ({args.robots} robots x {args.callbacks} callbacks, "
          f"{args.hogs} hogs): main thread busy idle {100 * idle['busy_share']:.1f} %, old "
          f"{100 * old['busy_share']:.1f} %, new {100 * new['busy_share']:.1f} % (old / new "
          f"{old['busy_share'] / max(new['busy_share'], 1e-9):.1f}x); on the CPU idle "
          f"{100 * idle['cpu_share']:.1f} %, old {100 * old['cpu_share']:.1f} %, new "
          f"{100 * new['cpu_share']:.1f} % (old / new "
          f"{old['cpu_share'] / max(new['cpu_share'], 1e-9):.1f}x); click old "
          f"{old['click_s']:.3f} s, new {new['click_s']:.3f} s (old / new "
          f"{old['click_s'] / max(new['click_s'], 1e-9):.1f}x)")
    if args.out is not None:
        args.out.write_text(json.dumps({"records": records, "median": med}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
