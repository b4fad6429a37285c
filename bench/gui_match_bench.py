"""What watching a team match costs the browser: the demo's default views, world view shown
against collapsed.

``python -m debug_gui.demo --robots R`` (a real match, as ``scripts/gui_demo.sh`` runs it)
and headless chromium showing its page as it opens: the world view for the team above every
robot's components. Once the game plays, windows of ``--seconds`` alternate between the
world view shown and collapsed (a collapsed view closes its feeds and sends nothing), in
the same page and the same match, so both see the same load. Per window: the renderer's
main-thread busy share and CPU share (Chrome DevTools Protocol ``Performance.getMetrics``
``TaskDuration`` and ``ThreadTime``, as bench/gui_page_bench.py measures the landing page).
Printed per window and as medians, with the ratio shown / collapsed: what the world view
adds to the components tables a match's page shows anyway. The window is tall enough
(``--height``) that the tables are in sight either way: rows out of sight are not drawn,
so in a short window collapsing the world view brings rows into sight and costs more.

Run: ``source scripts/env.sh && python bench/gui_match_bench.py --robots 2v1 --windows 6``
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.gui_page_bench import _task_s  # noqa: E402
from efficient_comm.testing import isolated_domain_id, ros_env  # noqa: E402
from tests._gui import Process, new_browser, started, text_of, wait_for  # noqa: E402

#: Click the world panel's header (collapse, or open again).
_TOGGLE = """
for (const e of document.querySelectorAll('.q-expansion-item__container > .q-item'))
  if (e.textContent.includes('World')) e.click();
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", default="2v1", help="the match's robots (default 2v1)")
    ap.add_argument("--windows", type=int, default=6, help="measurement windows (even)")
    ap.add_argument("--seconds", type=float, default=12.0, help="seconds per window")
    ap.add_argument("--height", type=int, default=2600, help="the browser window's height "
                    "(px; the width is 1600)")
    args = ap.parse_args()
    figures: dict[str, list[tuple[float, float]]] = {"shown": [], "collapsed": []}
    with tempfile.TemporaryDirectory(prefix="gui_match_bench_") as tmp:
        log = Path(tmp, "demo.log")
        cmd = [sys.executable, "-m", "debug_gui.demo", "--robots", args.robots, "--port", "0",
               "--out-dir", str(Path(tmp, "match")), "--report", str(Path(tmp, "report.md"))]
        with started(cmd, env=ros_env(isolated_domain_id()), log=log) as proc:
            demo = Process(proc=proc, log=log)
            url = wait_for(lambda: re.search(r"at (http://\S+)", demo.output()),
                           timeout_s=120, what="the URL", alive=[demo]).group(1)
            browser = new_browser()
            try:
                browser.set_window_size(1600, args.height)
                browser.get(url)
                wait_for(lambda: "playing" in text_of(browser, "world-game-team"),
                         timeout_s=300, what="the game playing", alive=[demo])
                browser.execute_cdp_cmd("Performance.enable", {})
                state = "shown"
                for _ in range(args.windows):
                    (busy0, cpu0), t0 = _task_s(browser), time.monotonic()
                    time.sleep(args.seconds)  # the measurement window, not synchronisation
                    (busy1, cpu1), t1 = _task_s(browser), time.monotonic()
                    share = ((busy1 - busy0) / (t1 - t0), (cpu1 - cpu0) / (t1 - t0))
                    figures[state].append(share)
                    print(f"world view {state}: main thread {100 * share[0]:.1f} % busy "
                          f"({100 * share[1]:.1f} % on the CPU); load "
                          f"{os.getloadavg()[0]:.1f}", flush=True)
                    browser.execute_script(_TOGGLE)
                    state = "collapsed" if state == "shown" else "shown"
            finally:
                browser.quit()
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=120)
    med = {k: (statistics.median(b for b, _ in v), statistics.median(c for _, c in v))
           for k, v in figures.items() if v}
    if len(med) == 2:
        (sb, sc), (cb, cc) = med["shown"], med["collapsed"]
        print(f"median ({args.robots}): busy shown {100 * sb:.1f} %, collapsed "
              f"{100 * cb:.1f} % (shown / collapsed {sb / max(cb, 1e-9):.2f}x); CPU shown "
              f"{100 * sc:.1f} %, collapsed {100 * cc:.1f} % "
              f"({sc / max(cc, 1e-9):.2f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
