#!/usr/bin/env python3
"""Live-edit protocol: does the land follow the pen?

Replays four edits of the example scene (an end-handle drag, a whole-stroke move, a width slider
dragged in the side panel, a new ridge drawn), 16 edit frames each, in the real editor under a
deterministic work budget, and reports per run:

  changed   edit frames whose displayed heights moved by more than 1 mm at some probe
  lag       largest `lag_m` after the third edit frame over the edit's total height change at the
            probes (converged end state against converged start state)
  settle    frames after the last edit until the solver meets its tolerance
  cap       largest solver work of an edit frame over the work budget (the edit cap is 4 budgets,
            plus the last unit of work that crossed it)

Usage: scripts/live_edit_protocol.py [--bin target/release/terrasketch] [--sizes 256,1024,4096]
       [--backends cpu,gpu] [--kinds handle,move,slider,draw] [--budget-wu 4] [--json]
Needs a display or xvfb-run (as the editor tests). The GPU solver runs on whatever adapter wgpu
picks (WGPU_BACKEND=vulkan: lavapipe on machines without a GPU, where 1024^2 takes minutes).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

EDIT_FRAMES = 16
# Probes along stroke 1 of the example scene (its dragged end is at 7600, 5200) and beside it.
STROKE_PROBES_M = [[7600, 5200], [6000, 6000], [6500, 6300], [7000, 5500], [5600, 7300]]
# The new ridge of `draw`, drawn in the top view, and probes on and beside it (window pixels).
DRAW_FROM_PX, DRAW_TO_PX = [520, 420], [820, 260]
DRAW_PROBES_PX = [[600, 378], [670, 340], [750, 298], [670, 380]]


def events(kind):
    """The session's events for one kind of edit."""
    head = [{"wait_converged": 2000}, {"mark": "ready"}, {"wait": 1}]
    tail = [
        {"mark": "stopped"},
        {"wait": 12},
        {"release": {}},
        {"wait_converged": 600},
        {"mark": "settled"},
        {"wait": 1},
    ]
    if kind == "handle":
        edit = [
            {"tool": "select"},
            {"press_handle": {"stroke": 1, "end": "last"}},
            {"mark": "editing"},
            {"drag_by": {"to": [80, 40], "frames": EDIT_FRAMES}},
        ]
    elif kind == "move":
        edit = [
            {"tool": "select"},
            {"press_handle": {"stroke": 1, "end": "middle"}},
            {"mark": "editing"},
            {"drag_by": {"to": [64, 32], "frames": EDIT_FRAMES}},
        ]
    elif kind == "slider":
        edit = [{"select": 1}, {"mark": "editing"}]
        for i in range(EDIT_FRAMES):
            edit += [{"set": {"width_m": 900 + 60 * (i + 1)}}, {"wait": 1}]
        # Nothing is held: the release is a no-op.
    elif kind == "draw":
        edit = [
            {"tool": "ridge"},
            {"move": DRAW_FROM_PX},
            {"press": {"at": DRAW_FROM_PX}},
            {"mark": "editing"},
            {"drag_to": {"to": DRAW_TO_PX, "frames": EDIT_FRAMES}},
        ]
    else:
        raise SystemExit(f"unknown kind {kind}")
    return head + edit + tail


def session(kind, size, backend, budget_wu):
    s = {
        "format": "terrasketch-session",
        "version": 1,
        "sketch": "example",
        "size": size,
        "window_px": [960, 600],
        "solver_budget_wu": budget_wu,
        "backend": backend,
        "lag": True,
        "events": events(kind),
    }
    if kind == "draw":
        s["camera"] = "top"
        s["probes_px"] = DRAW_PROBES_PX
    else:
        s["probes_m"] = STROKE_PROBES_M
    return s


def run(binary, sess):
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "session.json")
        log = os.path.join(d, "frames.jsonl")
        with open(path, "w") as f:
            json.dump(sess, f)
        cmd = [binary, "--replay", path, "--log", log]
        if not os.environ.get("DISPLAY"):
            cmd = ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24"] + cmd
        env = dict(os.environ, TERRASKETCH_RECOVERY_DIR=d)
        env.setdefault("WGPU_BACKEND", "vulkan")
        p = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if p.returncode != 0:
            raise SystemExit(f"editor failed ({p.returncode}):\n{p.stderr}")
        with open(log) as f:
            return [json.loads(line) for line in f]


def measure(log, budget_wu):
    """The protocol's figures from one frame log."""
    editing = [f for f in log if f["mark"] == "editing"]
    ready = [f for f in log if f["mark"] == "ready"][-1]
    settled = [f for f in log if f["mark"] == "settled"][-1]
    # Edit frames are those whose sketch differs from the previous frame's.
    before = {f["frame"]: f for f in log}
    edit_frames = [
        f for f in editing if before.get(f["frame"] - 1, f)["sketch_digest"] != f["sketch_digest"]
    ]

    def moved(a, b):
        return any(
            x is not None and y is not None and abs(x - y) > 1e-3
            for x, y in zip(a["probe_heights_m"], b["probe_heights_m"])
        )

    changed = sum(1 for f in edit_frames if moved(before[f["frame"] - 1], f))
    total = max(
        (abs(a - b) for a, b in zip(settled["probe_heights_m"], ready["probe_heights_m"])
         if a is not None and b is not None),
        default=0.0,
    )
    lags = [f["lag_m"] for f in edit_frames[3:] if f["lag_m"] is not None]
    last = edit_frames[-1]["frame"] if edit_frames else 0
    settle = next(
        (f["frame"] - last for f in log if f["frame"] > last and f["converged"]), None
    )
    cap = max((f["work_units"] for f in edit_frames), default=0.0) / budget_wu
    return {
        "edit_frames": len(edit_frames),
        "changed": changed,
        "changed_share": changed / max(1, len(edit_frames)),
        "total_change_m": total,
        "max_lag_m": max(lags, default=None),
        "lag_share": (max(lags) / total) if lags and total > 0 else None,
        "settle_frames": settle,
        "max_edit_work_over_budget": cap,
        "max_edit_solver_ms": max((f["solver_ms"] for f in edit_frames), default=0.0),
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="target/release/terrasketch")
    ap.add_argument("--sizes", default="256,1024,4096")
    ap.add_argument("--backends", default="cpu")
    ap.add_argument("--kinds", default="handle,move,slider,draw")
    ap.add_argument("--budget-wu", type=float, default=4.0)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    rows = []
    for backend in a.backends.split(","):
        for size in [int(s) for s in a.sizes.split(",")]:
            for kind in a.kinds.split(","):
                log = run(a.bin, session(kind, size, backend, a.budget_wu))
                r = dict(backend=backend, size=size, kind=kind, **measure(log, a.budget_wu))
                rows.append(r)
                if a.json:
                    print(json.dumps(r), flush=True)
                else:
                    lag = "-" if r["lag_share"] is None else f"{100 * r['lag_share']:.1f}%"
                    print(
                        f"{backend:4} {size:5} {kind:7} changed {r['changed']:2}/{r['edit_frames']:2}"
                        f"  lag {lag:>6} of {r['total_change_m']:7.1f} m"
                        f"  settle {r['settle_frames']}  edit work {r['max_edit_work_over_budget']:.2f} budgets"
                        f"  solver {r['max_edit_solver_ms']:.0f} ms",
                        flush=True,
                    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
