"""``posed demo [--seconds 20]``: run the whole daemon on the embedded default input, watch what it publishes
from a separate Zenoh session (one line per second: fps, latency, knee and hip angles), then stop it.

The embedded input is the real squat video of the shared test data (``$POSED_SHARED_DATA``, default
``../shared/data`` beside the checkout) when it is there, else a landmark recording generated from a simulated
body; the first line says which, and where to point ``POSED_SHARED_DATA`` for the real one."""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

from posed.commands import add_config_args
from posed.commands._child import free_endpoint, run_command, stop

STOP_TIMEOUT_S = 10.0   # for the daemon's clean shutdown after SIGTERM, before SIGKILL


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("demo", help="run the daemon on the embedded demo input for a while and show its output",
                            description="Runs the daemon on the real squat video of the shared test data "
                                        "($POSED_SHARED_DATA/reference/tfjs_pose_squats/pose_squats.mp4; "
                                        "POSED_SHARED_DATA defaults to ../shared/data beside the checkout) or, "
                                        "without it, on a generated landmark recording; it says which.")
    parser.add_argument("--seconds", type=float, default=20.0, help="how long to publish (default 20)")
    add_config_args(parser, source=False, example="fitting.restarts=10")
    parser.add_argument("--source", metavar="URI", help="input instead of the embedded demo video")
    parser.set_defaults(func=_demo)


def describe_input(source: str | None) -> str:
    """What the demo replays, in one line: ``--source``, the real squat video of the shared test data, or the
    generated recording (and where to put the real data to get the video instead)."""
    from posed.daemon.preflight import SQUAT_VIDEO, cache_dir, shared_data

    if source:
        return f"posed demo: replaying {source} (--source), looped"
    video = shared_data() / SQUAT_VIDEO
    if video.is_file():
        return (f"posed demo: replaying real video, {video} (tfjs-models' squat clip: one woman, front view, "
                "65 frames at 5 fps), looped; the landmark stage and the fit run on every frame")
    how = ("POSED_SHARED_DATA is set to " + os.environ["POSED_SHARED_DATA"] if os.environ.get("POSED_SHARED_DATA")
           else "POSED_SHARED_DATA is not set")
    return (f"posed demo: no real video at {video} ({how}): replaying a GENERATED recording instead, "
            f"{cache_dir() / 'demo_squats.landmarks.jsonl'} (a simulated body doing three squats, landmarks only: "
            "the landmark stage does not run). For the real video: POSED_SHARED_DATA=/path/to/shared/data "
            "(the folder holding reference/tfjs_pose_squats/pose_squats.mp4)")


def _demo(args: argparse.Namespace) -> int:
    print(describe_input(args.source), flush=True)
    endpoint = free_endpoint()
    state = tempfile.mkdtemp(prefix="posed-demo-")
    # the embedded demo input unless --source (never the camera of a config found in /etc/posed)
    demo_input = [] if args.source else ["source.type=file", "source.path="]
    cmd = run_command([*demo_input, "source.loop=true", f"zenoh.listen=[{endpoint}]", "zenoh.connect=[]",
                       "zenoh.mode=peer", f"pipeline.state_dir={state}", "robot_id=demo", "logging.format=json"],
                      args.config, args.source, args.overrides)
    try:
        code = _run_demo(args, cmd, endpoint, state)
    except BaseException:
        shutil.rmtree(state, ignore_errors=True)
        raise
    if code == 0:
        shutil.rmtree(state, ignore_errors=True)   # its journal, history and logs: nothing to keep
    else:
        print(f"posed demo: the daemon's logs are kept in {state}", file=sys.stderr)
    return code


def _run_demo(args: argparse.Namespace, cmd: list[str], endpoint: str, state: str) -> int:
    from posed.commands._viewer import Summary, subscribe
    from posed.commands.watch import open_viewer

    log_path = os.path.join(state, "daemon.log")
    print(f"posed demo: starting the daemon, listening on {endpoint} (its logs are kept only if it fails)",
          flush=True)
    err_path = os.path.join(state, "daemon.err")
    with open(log_path, "w") as log, open(err_path, "w") as errlog:
        daemon = subprocess.Popen(cmd, stdout=log, stderr=errlog, text=True)
    summary = Summary()
    session = None
    t0 = time.monotonic()
    try:
        deadline = t0 + 60.0
        while session is None and daemon.poll() is None and time.monotonic() < deadline:
            session = open_viewer(endpoint, 1.0, quiet=True) if _listening(endpoint) else None
            if session is None:
                time.sleep(0.2)
        if session is None:
            return _failed(daemon, "the daemon did not come up", err_path)
        with session:
            keep = subscribe(session, "demo", summary)
            t_line = time.monotonic() + 1.0
            t_start = time.monotonic()
            while daemon.poll() is None:
                time.sleep(max(0.0, t_line - time.monotonic()))
                for line in summary.line(t_line - t_start):
                    print(line, flush=True)
                t_line += 1.0
                first = summary.first_pose_at
                if first is not None and time.monotonic() - first >= args.seconds:
                    break
                if first is None and time.monotonic() - t_start > 120:
                    print("posed demo: no pose within 120 s", file=sys.stderr)
                    break
            del keep
            if daemon.poll() is not None:
                return _failed(daemon, "the daemon stopped early", err_path)
    finally:
        stop(daemon, STOP_TIMEOUT_S)
    final = summary.final()
    lat = final["latency_ms"]
    knee = final["knee_deg"]
    print(f"posed demo: {final['poses']} poses ({final['poses_ok']} with a person) at {final['fps']} fps; "
          f"latency p50 {lat['p50']} ms, p95 {lat['p95']} ms; knee flexion "
          + (f"{knee[0]:.0f}..{knee[1]:.0f} deg" if knee[0] is not None else "-")
          + f"; {final['events']} fall events; daemon exit status {daemon.returncode}", flush=True)
    return 0 if daemon.returncode == 0 and final["poses_ok"] > 0 else 1


def _listening(endpoint: str) -> bool:
    import socket

    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    with socket.socket() as s:
        s.settimeout(0.2)
        return s.connect_ex((host, int(port))) == 0


def _failed(daemon: subprocess.Popen, what: str, err_path: str) -> int:
    """Stop the daemon (it may still be running when it never came up) and show its stderr."""
    stop(daemon, STOP_TIMEOUT_S)
    print(f"posed demo: {what} (exit status {daemon.returncode})", file=sys.stderr)
    with open(err_path) as fh:
        err = fh.read()
    if err:
        print(err.rstrip(), file=sys.stderr)
    return daemon.returncode or 1
