"""Watch a running ``swarm-up --dashboard`` with headless Chromium and report what the page got
(not a test): the updates per second it received, the robots it drew, its last KPIs; optionally
a screenshot.

Usage (from the repository root, while swarm-up runs)::

    python tools/dash_probe.py http://127.0.0.1:8080/ [--select Srobot3]
        [--screenshot docs/dashboard.png --shot-after 40] [--max-s 900]

It polls the page once a second until the dashboard goes away (no new frame for 5 s after the
first) or ``--max-s``, then prints one JSON line: ``fps_median`` / ``fps_min`` (over the polls
once the page had 50 frames: the rate of the last 5 s as the page measures it), ``frames``,
``drawn_max``, ``robots``, ``kpi`` (the last frame's).  Needs Debian's ``chromium``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.support.browser import Chromium  # noqa: E402


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("url")
    p.add_argument("--select", default=None, help="open this robot's view (scan subscribed)")
    p.add_argument("--screenshot", type=Path, default=None)
    p.add_argument("--shot-after", type=float, default=30.0,
                   help="wall seconds after the first frame to take the screenshot")
    p.add_argument("--size", default="1400x900", help="window size WxH [px]")
    p.add_argument("--max-s", type=float, default=900.0)
    a = p.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    fps, drawn_max, last, first_frame_t, shot = [], 0, None, None, False
    last_frames, last_change = 0, time.monotonic()
    t0 = time.monotonic()
    with Chromium(a.url, size=(w, h)) as browser:
        selected = False
        while time.monotonic() - t0 < a.max_s:
            time.sleep(1.0)
            now = time.monotonic()
            try:
                stats = browser.evaluate("window.dash && window.dash.stats()")
            except RuntimeError:
                stats = None
            if not stats:
                if first_frame_t is not None and now - last_change > 10.0:
                    break  # the page stopped answering after the run
                continue
            if stats["frames"] != last_frames:
                last_frames, last_change = stats["frames"], now
            elif stats["frames"] and now - last_change > 5.0:
                break  # the dashboard went away
            if stats["frames"] and first_frame_t is None:
                first_frame_t = now
            if a.select and not selected and stats["drawn"]:
                browser.evaluate(f"window.dash.select({json.dumps(a.select)})")
                selected = True
            if stats["frames"] >= 50 and stats["drawn"]:
                fps.append(stats["fps"])
            drawn_max = max(drawn_max, stats["drawn"])
            last = stats
            if (a.screenshot and not shot and first_frame_t is not None
                    and now - first_frame_t >= a.shot_after):
                browser.screenshot(a.screenshot)
                shot = True
                print(f"screenshot: {a.screenshot}", file=sys.stderr)
    out = {"fps_median": statistics.median(fps) if fps else None,
           "fps_min": min(fps) if fps else None, "polls": len(fps),
           "frames": last["frames"] if last else 0, "drawn_max": drawn_max,
           "robots": last["robots"] if last else None, "kpi": last["kpi"] if last else None}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
