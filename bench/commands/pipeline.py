"""The whole pipeline on real video through the real model: fps, latency per stage and end to end, drops,
CPU and memory per process.

Input: the real squat video of the shared test data, letterboxed to 640x480 at 10 fps (written once to the
cache dir), replayed in a loop by ``posed run`` in a subprocess; a separate Zenoh session takes the pose and
status topics. ``--input 1080p``: a full-HD camera instead, the real s2d_enter clip (two people outdoors)
brought to 1920x1080 at its own 30 fps (written once to the cache dir), which the capture stage scales down to
960x540 and thins to 10 fps: the frame budget with a 1080p source (issue 39). Phases (``--phase``): ``paced`` (real-time replay at 10 fps: published fraction and latency
targets), ``unpaced`` (replay as fast as the pipeline takes it: throughput target), or ``both``.

Targets (issue): paced 10 fps -> >= 99 % of frames published, capture->publish latency p95 <= 80 ms;
unpaced -> >= 20 fps; memory: no growth over a 10-minute run (``--duration 600``), judged on the anonymous
memory of all processes after the first minute (daemon/proc/procstat.py says why not PSS or USS).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
import threading
import time
from pathlib import Path

from posed.commands import add_config_args
from posed.commands._child import free_endpoint, run_command, stop
from posed.daemon.proc.stats import percentile_summary

TARGET_PUBLISHED = 0.99
TARGET_P95_MS = 80.0
TARGET_UNPACED_FPS = 20.0
GROWTH_LIMIT_MB = 10.0
BENCH_SIZE = (640, 480)
BENCH_FPS = 10.0
STOP_TIMEOUT_S = 15.0   # for the daemon's clean shutdown after SIGTERM, before SIGKILL


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--duration", type=float, default=30.0, help="measured seconds per phase (default 30)")
    parser.add_argument("--phase", choices=("paced", "unpaced", "both"), default="both",
                        help="paced: real-time replay (published fraction, latency); unpaced: as fast as it "
                             "goes (throughput); both (default)")
    parser.add_argument("--source", metavar="PATH", help="a video to replay instead of the squat video (used as is)")
    parser.add_argument("--clips", action="store_true",
                        help="instead: every real clip of the shared data (any size, portrait, GIF, 5-60 fps) through "
                             "posed run, default config, paced, to its end: poses published vs the frames taken "
                             "(bench/clips.py; target >= 90 %%)")
    parser.add_argument("--input", choices=("squat", "1080p"), default="squat",
                        help="squat: the squat video at 640x480, 10 fps (default); 1080p: a real clip at 1920x1080, "
                             "30 fps, as a full-HD camera gives it")
    parser.add_argument("--warmup", type=float, default=3.0, help="seconds after the first pose before measuring")
    add_config_args(parser, source=False)


def bench_video() -> Path:
    """The squat video letterboxed to 640x480 at 10 fps (each source frame shown twice: 5 -> 10 fps)."""
    import cv2
    import numpy as np

    from posed.daemon.preflight import SQUAT_VIDEO, cache_dir, shared_data

    out = cache_dir() / "bench" / "pose_squats_640x480_10fps.mp4"
    if out.is_file():
        return out
    src = shared_data() / SQUAT_VIDEO
    if not src.is_file():
        raise FileNotFoundError(f"the bench input {src} is missing: the shared test data must sit at "
                                f"{shared_data()} (set POSED_SHARED_DATA)")
    out.parent.mkdir(parents=True, exist_ok=True)
    cap = cv2.VideoCapture(str(src))
    fps = cap.get(cv2.CAP_PROP_FPS) or 5.0
    repeat = max(1, round(BENCH_FPS / fps))
    tmp = out.with_name(out.stem + ".tmp.mp4")
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), BENCH_FPS, BENCH_SIZE)
    w, h = BENCH_SIZE
    n = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        scale = min(w / frame.shape[1], h / frame.shape[0])
        small = cv2.resize(frame, (round(frame.shape[1] * scale), round(frame.shape[0] * scale)),
                           interpolation=cv2.INTER_AREA)
        canvas = np.zeros((h, w, 3), np.uint8)
        y0, x0 = (h - small.shape[0]) // 2, (w - small.shape[1]) // 2
        canvas[y0:y0 + small.shape[0], x0:x0 + small.shape[1]] = small
        for _ in range(repeat):
            writer.write(canvas)
            n += 1
    writer.release()
    cap.release()
    if n == 0:
        raise RuntimeError(f"no frame could be read from {src}")
    tmp.replace(out)
    return out


def bench_video_1080p() -> Path:
    """The real s2d_enter clip (1768x994, 30 fps, 230 frames) brought to 1920x1080 at 30 fps, as a 1080p camera."""
    import cv2

    from posed.daemon.preflight import cache_dir, shared_data

    out = cache_dir() / "bench" / "s2d_enter_1920x1080_30fps.avi"
    if out.is_file():
        return out
    src = shared_data() / "reference" / "multi_person" / "s2d_enter.mp4"
    if not src.is_file():
        raise FileNotFoundError(f"the bench input {src} is missing: the shared test data must sit at "
                                f"{shared_data()} (set POSED_SHARED_DATA)")
    out.parent.mkdir(parents=True, exist_ok=True)
    cap = cv2.VideoCapture(str(src))
    tmp = out.with_name(out.stem + ".tmp.avi")
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"MJPG"), cap.get(cv2.CAP_PROP_FPS) or 30.0,
                             (1920, 1080))
    n = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        writer.write(cv2.resize(frame, (1920, 1080), interpolation=cv2.INTER_CUBIC))
        n += 1
    writer.release()
    cap.release()
    if n == 0:
        raise RuntimeError(f"no frame could be read from {src}")
    tmp.replace(out)
    return out


class _Collector:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.poses: list[tuple[float, dict]] = []
        self.statuses: list[tuple[float, dict]] = []

    def on_pose(self, sample) -> None:
        obj = json.loads(sample.payload.to_string())
        with self.lock:
            self.poses.append((time.monotonic(), obj))

    def on_status(self, sample) -> None:
        obj = json.loads(sample.payload.to_string())
        with self.lock:
            self.statuses.append((time.monotonic(), obj))


def run_phase(name: str, video: Path, args: argparse.Namespace) -> dict:
    from posed.commands.watch import open_viewer

    paced = name == "paced"
    endpoint = free_endpoint()
    state = tempfile.mkdtemp(prefix="posed-bench-")
    cmd = run_command(["source.loop=true", f"source.realtime={'true' if paced else 'false'}",
                       f"pipeline.target_fps={BENCH_FPS if paced else 60}", f"zenoh.listen=[{endpoint}]",
                       "zenoh.connect=[]", "zenoh.mode=peer", f"pipeline.state_dir={state}", "robot_id=bench",
                       "pipeline.status_period_s=1", "logging.format=json"],
                      args.config, f"file:{video}", args.overrides)
    log = open(os.path.join(state, "daemon.log"), "w")
    err = open(os.path.join(state, "daemon.err"), "w")
    daemon = subprocess.Popen(cmd, stdout=log, stderr=err)
    col = _Collector()
    try:
        session = None
        deadline = time.monotonic() + 120
        while session is None:
            if daemon.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the daemon did not start (exit {daemon.returncode}); see {state}/daemon.err")
            session = open_viewer(endpoint, 0.5, quiet=True)
        with session:
            keep = [session.declare_subscriber("posed/bench/pose", col.on_pose,),
                    session.declare_subscriber("posed/bench/status", col.on_status)]
            while not col.poses:
                if daemon.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"no pose from the daemon (exit {daemon.returncode}); see {state}")
                time.sleep(0.1)
            time.sleep(args.warmup)
            with col.lock:
                t_start = time.monotonic()
                status0 = col.statuses[-1][1] if col.statuses else None
            time.sleep(args.duration)
            time.sleep(1.1)                       # one more status after the window
            with col.lock:
                t_end = t_start + args.duration
                poses = [p for t, p in col.poses if t_start <= t < t_end]
                statuses = [s for t, s in col.statuses if t >= t_start]
            del keep
    finally:
        stop(daemon, STOP_TIMEOUT_S)
        log.close()
        err.close()
    return summarize(name, poses, status0, statuses, args.duration, daemon.returncode)


def summarize(name: str, poses: list[dict], status0: dict | None, statuses: list[dict], duration: float,
              exit_code: int | None) -> dict:
    status1 = statuses[-1] if statuses else None
    out: dict = {"phase": name, "duration_s": duration, "poses_received": len(poses),
                 "fps": round(len(poses) / duration, 2), "daemon_exit": exit_code}
    timing: dict[str, list[float]] = {}
    for p in poses:
        for k, v in (p.get("timing_ms") or {}).items():
            timing.setdefault(k, []).append(float(v))
    out["latency_ms"] = {k: percentile_summary(v, 1) for k, v in timing.items()}
    out["persons"] = sum(1 for p in poses if p.get("ok"))
    if status0 and status1:
        d = {}
        for stage, st in status1["stages"].items():
            st0 = status0["stages"].get(stage, {})
            d[stage] = {"frames": st["frames"] - st0.get("frames", 0), "drops": st["drops"] - st0.get("drops", 0),
                        "skipped": st["skipped"] - st0.get("skipped", 0), "restarts": st["restarts"],
                        "step_ms_p95": st["step_ms"]["p95"]}
        out["stages"] = d
        cap = d.get("capture", {}).get("frames", 0)
        pub = d.get("publisher", {}).get("frames", 0)
        out["published_fraction"] = round(pub / cap, 4) if cap else None
        procs: dict[str, dict] = {}
        for st in statuses:
            for stage, s in [*st["stages"].items(), ("supervisor", st["supervisor"])]:
                e = procs.setdefault(stage, {"cpu": [], "rss": [], "pss": [], "uss": [], "anon": []})
                if s.get("cpu_pct") is not None:
                    e["cpu"].append(s["cpu_pct"])
                if s.get("rss_mb") is not None:
                    e["rss"].append(s["rss_mb"])
                if s.get("pss_mb") is not None:
                    e["pss"].append(s["pss_mb"])
                if s.get("uss_mb") is not None:
                    e["uss"].append(s["uss_mb"])
                if s.get("anon_mb") is not None:
                    e["anon"].append(s["anon_mb"])
        out["processes"] = {k: {"cpu_pct_mean": round(sum(v["cpu"]) / len(v["cpu"]), 1) if v["cpu"] else None,
                                "rss_mb_end": v["rss"][-1] if v["rss"] else None,
                                "pss_mb_start": v["pss"][0] if v["pss"] else None,
                                "pss_mb_end": v["pss"][-1] if v["pss"] else None,
                                "uss_mb_start": v["uss"][0] if v["uss"] else None,
                                "uss_mb_end": v["uss"][-1] if v["uss"] else None,
                                "anon_mb_start": v["anon"][0] if v["anon"] else None,
                                "anon_mb_end": v["anon"][-1] if v["anon"] else None} for k, v in procs.items()}
        totals = [s["memory_mb"] for s in statuses]
        private = [s.get("anon_mb", 0.0) for s in statuses]
        # after the first minute (allocator pools and caches fill) when the run is long enough
        settle = 60 if duration >= 300 else 0
        up0 = statuses[0]["uptime_s"]
        ref = next((i for i, s in enumerate(statuses) if s["uptime_s"] - up0 >= settle), 0)
        out["memory_mb"] = {"start": totals[0], "end": totals[-1], "max": max(totals),
                            "anon_start": private[0], "anon_after_settle": private[ref],
                            "settle_s": settle, "anon_end": private[-1],
                            "growth": round(private[-1] - private[ref], 1)}
    targets = {}
    if name == "paced":
        frac = out.get("published_fraction")
        p95 = (out["latency_ms"].get("total") or {}).get("p95")
        targets["published_fraction>=0.99"] = frac is not None and frac >= TARGET_PUBLISHED
        targets["latency_p95<=80ms"] = p95 is not None and p95 <= TARGET_P95_MS
    else:
        targets["fps>=20"] = out["fps"] >= TARGET_UNPACED_FPS
    if "memory_mb" in out and duration >= 300:
        targets["memory_growth<=10MB"] = out["memory_mb"]["growth"] <= GROWTH_LIMIT_MB
    out["targets_met"] = targets
    return out


def run(args: argparse.Namespace) -> int:
    if getattr(args, "clips", False):
        from posed.bench.clips import measure as measure_clips
        from posed.daemon.preflight import shared_data

        rows = measure_clips(shared_data())
        for row in rows:
            print(json.dumps(row) if args.json else "  ".join(f"{k} {v}" for k, v in row.items()), flush=True)
        if not args.json:
            print("all targets met" if all(r["target_met"] for r in rows) else "some targets MISSED")
        return 0
    video = Path(args.source) if args.source else (bench_video_1080p() if getattr(args, "input", "squat") == "1080p"
                                                   else bench_video())
    phases = ("paced", "unpaced") if args.phase == "both" else (args.phase,)
    results = []
    for phase in phases:
        if not args.json:
            print(f"bench pipeline: {phase} phase, {args.duration:g} s on {video.name} ...", flush=True)
        results.append(run_phase(phase, video, args))
    report = {"input": str(video), "machine_cores": os.cpu_count(), "phases": results,
              "all_targets_met": all(all(r["targets_met"].values()) for r in results)}
    if args.json:
        print(json.dumps(report))
    else:
        for r in results:
            print(_text(r))
        print("all targets met" if report["all_targets_met"] else "some targets MISSED")
    return 0


def _text(r: dict) -> str:
    lines = [f"== {r['phase']}: {r['fps']} fps published ({r['poses_received']} poses in {r['duration_s']:g} s, "
             f"{r['persons']} with a person); published fraction {r.get('published_fraction')}"]
    for k, v in r["latency_ms"].items():
        lines.append(f"   {k:>10s} ms  p50 {v['p50']}  p95 {v['p95']}  max {v['max']}")
    for stage, d in (r.get("stages") or {}).items():
        lines.append(f"   {stage:>10s}: frames {d['frames']} drops {d['drops']} skipped {d['skipped']} "
                     f"restarts {d['restarts']} step p95 {d['step_ms_p95']} ms")
    for proc, d in (r.get("processes") or {}).items():
        lines.append(f"   {proc:>10s}: cpu {d['cpu_pct_mean']} %  rss {d['rss_mb_end']} MB  pss {d['pss_mb_start']}"
                     f" -> {d['pss_mb_end']} MB  anonymous {d['anon_mb_start']} -> {d['anon_mb_end']} MB")
    if "memory_mb" in r:
        m = r["memory_mb"]
        lines.append(f"   memory: sum of PSS {m['start']} -> {m['end']} MB (max {m['max']}); anonymous "
                     f"{m['anon_start']} -> {m['anon_after_settle']} (after {m['settle_s']} s) -> {m['anon_end']} MB, "
                     f"growth {m['growth']} MB")
    lines.append("   targets: " + ", ".join(f"{k} {'met' if v else 'MISSED'}" for k, v in r["targets_met"].items()))
    return "\n".join(lines)
