"""What ``posed watch`` and ``posed demo`` show: the daemon's topics folded into one line per second, and a
line of its own when the absence notice begins or ends (``ROBOT: PERSON NOT SEEN FOR ...``, ``ROBOT: person seen
again after ...``: :func:`client.presence_change`, once per change, not on every status)."""

from __future__ import annotations

import json
import threading
import time

from posed.client import Status, dark_note, presence_change
from posed.daemon.proc.stats import percentile_summary


def measured(pose: dict) -> dict[str, float]:
    """The angles a pose message measured (fitting.measured), by symbol; none for a malformed one."""
    from posed.fitting import FitResult

    try:
        return FitResult.from_json(pose).measured_angles()
    except (ValueError, TypeError, KeyError):
        return {}


class Summary:
    """Collects pose, status and event messages (from Zenoh callback threads) and renders a line per period."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._poses: list[dict] = []
        self._received: list[float] = []
        self.status: dict | None = None
        self.events: list[dict] = []
        self._new_events: list[dict] = []
        self.all_latency_ms: list[float] = []
        self.knee: list[float] = []
        self.hip: list[float] = []
        self.poses_total = 0
        self.poses_ok = 0
        self.first_pose_at: float | None = None
        self._presence = None                   # the last status's client.Presence
        self._notices: list[str] = []           # absence notice begun or ended, not yet printed

    # -- callbacks --------------------------------------------------------------------------------------
    def on_pose(self, sample) -> None:
        obj = json.loads(sample.payload.to_string())
        now = time.monotonic()
        with self._lock:
            self._poses.append(obj)
            self._received.append(now)
            self.poses_total += 1
            if self.first_pose_at is None:
                self.first_pose_at = now
            lat = (obj.get("timing_ms") or {}).get("total")
            if lat is not None:
                self.all_latency_ms.append(float(lat))
            if obj.get("ok"):
                self.poses_ok += 1
                ja = measured(obj)
                for key, store in (("theta_kn_l", self.knee), ("theta_kn_r", self.knee),
                                   ("theta_hp_l", self.hip), ("theta_hp_r", self.hip)):
                    if key in ja:
                        store.append(ja[key])

    def on_status(self, sample) -> None:
        obj = json.loads(sample.payload.to_string())
        try:
            presence = Status.from_json(obj).presence if isinstance(obj, dict) and "state" in obj else None
        except (ValueError, TypeError):     # a status the client cannot read: no word on presence
            presence = None
        with self._lock:
            self.status = obj
            said = presence_change(self._presence, presence)
            if said:
                self._notices.append(f"{obj.get('robot') or 'robot'}: {said}")
            if presence is not None or self._presence is None or not self._presence.absent:
                self._presence = presence       # a status without it does not end a notice (nor say it again)

    def take_notices(self) -> list[str]:
        """The absence notice's lines since the last call (``ROBOT: PERSON NOT SEEN FOR ...``, ``ROBOT: person
        seen again after ...``), each once."""
        with self._lock:
            out, self._notices = self._notices, []
            return out

    def on_event(self, sample) -> None:
        obj = json.loads(sample.payload.to_string())
        with self._lock:
            self.events.append(obj)
            self._new_events.append(obj)

    # -- rendering --------------------------------------------------------------------------------------
    def take_period(self) -> tuple[list[dict], list[dict], dict | None]:
        with self._lock:
            poses, self._poses = self._poses, []
            events, self._new_events = self._new_events, []
            return poses, events, self.status

    def line(self, elapsed_s: float, period_s: float = 1.0) -> list[str]:
        """The lines for the period just ended: fall events first, the absence notice's (:meth:`take_notices`),
        then the one-line summary."""
        poses, events, status = self.take_period()
        notices = self.take_notices()
        out = [f"{elapsed_s:5.1f}s  FALL {e.get('state', '?'):9s} id {str(e.get('id', ''))[:8]}  "
               f"confidence {e.get('confidence', 0):.2f}  features {','.join(e.get('features') or [])}"
               + (f"  person {e['person']}" if e.get("person") is not None else "")
               + (f" ({e['member']})" if e.get("member") else "")
               + (f"  [{n}]" if (n := event_notes(e)) else "")
               for e in events] + notices
        parts = [f"{elapsed_s:5.1f}s"]
        if not poses:
            parts.append(f"no poses ({waiting_for(status)})")
        else:
            # several people: one pose per person per frame, the frame's own first (the one shown)
            per_seq: dict = {}
            for p in poses:
                per_seq.setdefault(p.get("seq"), []).append(p)
            own = [ps[0] for ps in per_seq.values()]
            lat = [p["timing_ms"]["total"] for p in own if (p.get("timing_ms") or {}).get("total") is not None]
            ok = [p for p in own if p.get("ok")]
            parts.append(f"{len(per_seq) / period_s:5.1f} fps")
            most = max(len(ps) for ps in per_seq.values())
            if most > 1:
                parts.append(f"{most} people")
            if lat:
                s = percentile_summary(lat, 0)
                parts.append(f"latency p50 {s['p50']:4.0f} ms p95 {s['p95']:4.0f} ms")
            if ok:
                ja = measured(ok[-1])      # "-": not seen in that frame
                parts.append("knee L {} R {}  hip L {} R {} deg".format(
                    *(f"{ja[k]:5.1f}" if k in ja else "  -  " for k in ("theta_kn_l", "theta_kn_r", "theta_hp_l",
                                                                          "theta_hp_r"))))
            else:
                parts.append(f"no person ({poses[-1].get('reason', '')})")
            parts.append(f"seq {poses[-1].get('seq')}")
        if status:
            camera = status.get("camera") or {}
            cam = camera.get("state", "?")
            what = "recording" if camera.get("kind") == "file" or str(camera.get("source") or "").startswith(
                "file:") else "camera"
            cam += dark_note(camera)
            parts.append(f"[{status.get('state')}, {what} {cam}, drops {status.get('drops')}, "
                         f"restarts {status.get('restarts')}, {status.get('memory_mb')} MB]")
            decoded = Status.from_json(status) if "state" in status else None
            blind = decoded.not_watching if decoded else None
            if blind:       # posed runs but sees nothing: no fall can be detected (hooks.on_watch_lost's rule)
                since = decoded.watch.since_unix if decoded.watch is not None else None
                parts.append(f"NOT WATCHING ({blind}): a fall would not be detected"
                             + (f", since {_clock(since)}" if since is not None else ""))
            for r in decoded.restored_open if decoded else ():
                parts.append(f"fall {r.id[:8]} taken back after a restart: "
                             + ("alarm sent" if r.alarm else f"alarm due {_clock(r.due_unix)}"))
        out.append("  ".join(parts))
        return out

    def final(self) -> dict:
        with self._lock:
            lat = percentile_summary(self.all_latency_ms, 1)
            knee = (min(self.knee), max(self.knee)) if self.knee else (None, None)
            hip = (min(self.hip), max(self.hip)) if self.hip else (None, None)
            span = (self._received[-1] - self._received[0]) if len(self._received) > 1 else 0.0
            return {"poses": self.poses_total, "poses_ok": self.poses_ok,
                    "fps": round((len(self._received) - 1) / span, 2) if span > 0 else 0.0,
                    "latency_ms": lat, "knee_deg": knee, "hip_deg": hip, "events": len(self.events)}


def event_notes(e: dict) -> str:
    """A fall-event message's caveats in words (``posed events``' notes: restored, raised without frames)."""
    from posed.commands.events import notes

    return notes(e)


def _clock(t: float | None) -> str:
    """HH:MM:SS in this machine's zone."""
    import datetime as dt

    return "?" if t is None else dt.datetime.fromtimestamp(t).astimezone().strftime("%H:%M:%S %Z")


# What a stage still in its "starting" state is doing (daemon/stages: warm-up before READY).
WARMING = {"fitting": "compiling the fitting kernels (numba; quick once `posed warmup` ran)",
           "landmarks": "loading the landmark models", "capture": "opening the camera"}


def waiting_for(status: dict | None) -> str:
    """Why there are no poses yet, from the last status: the daemon's state, and while it starts, what each
    stage still warming up is doing."""
    if not status:
        return "waiting for the daemon"
    state = status.get("state", "?")
    if state != "starting":
        return state
    busy = [WARMING.get(name, f"{name} starting") for name, st in (status.get("stages") or {}).items()
            if isinstance(st, dict) and st.get("state") == "starting"]
    return "starting: " + "; ".join(busy) if busy else "starting"


def subscribe(session, robot: str, summary: Summary) -> list:
    """Declare the subscribers feeding ``summary``; keep the returned list referenced."""
    root = f"posed/{robot}"
    return [session.declare_subscriber(f"{root}/pose", summary.on_pose),
            session.declare_subscriber(f"{root}/status", summary.on_status),
            session.declare_subscriber(f"{root}/events/fall", summary.on_event)]
