"""Run one session of a clip protocol in this process (the clip tests start it under xvfb-run).

``python tests/clip_session.py PROTOCOL OUT [--slow N:K] [--crash-at T] [--resume] [--live]``

``--slow N:K`` makes a real dropped frame: the N-th clip presentation of the session (1-based)
sleeps 0.25 s before the first flip of its frame K, so that flip comes 0.25 s after the one
before it, as when the machine stalls; PsychoPy's own frame-interval recording sees the long
interval. Only our drawing function is slowed; PsychoPy is not touched.
``--crash-at T`` raises an exception when trial T starts (a crash; the rows before it are on disk).
``--live`` runs a live session (no simulated participant: the protocol must be passive);
otherwise a simulated participant answers in real time (every frame flipped, software paced).
"""

from __future__ import annotations

import argparse
import time

from experiments import run_session
from experiments.runner import SessionRunner
from experiments.screens import ClipTextures

SLOW_S = 0.25


def _slow_draw(presentation: int, frame: int) -> None:
    counter = {"n": 0}
    draw, init = ClipTextures.draw, ClipTextures.__init__

    def counting_init(self, *args, **kwargs):  # one ClipTextures per clip presentation
        counter["n"] += 1
        self._presentation = counter["n"]
        self._slowed = False
        init(self, *args, **kwargs)

    def slow(self, k: int) -> None:
        if self._presentation == presentation and k == frame and not self._slowed:
            self._slowed = True
            time.sleep(SLOW_S)
        draw(self, k)

    ClipTextures.__init__ = counting_init
    ClipTextures.draw = slow


def _crash_at(trial: int) -> None:
    run_trial = SessionRunner.run_trial

    def crashing(self, t, **kwargs):
        if t.trial == trial:
            raise RuntimeError(f"simulated crash at trial {trial}")
        return run_trial(self, t, **kwargs)

    SessionRunner.run_trial = crashing


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("protocol")
    ap.add_argument("out")
    ap.add_argument("--slow", default=None)
    ap.add_argument("--crash-at", type=int, default=None)
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--live", action="store_true")
    ap.add_argument("--screenshots", default=None)
    args = ap.parse_args()
    if args.slow:
        n, k = map(int, args.slow.split(":"))
        _slow_draw(n, k)
    if args.crash_at:
        _crash_at(args.crash_at)
    sim = {} if args.live else {"simulate": "default", "realtime": True}
    try:
        res = run_session(args.protocol, "01", out=args.out, resume=args.resume, windowed=True, report=False,
                          screenshot_dir=args.screenshots, **sim)
    except RuntimeError as exc:
        print(f"CRASHED: {exc}")
        return
    print(f"STATUS: {res.status} {res.completed}/{res.n_trials}")


if __name__ == "__main__":
    main()
