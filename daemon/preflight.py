"""Checks before anything is started, each problem with its fix; and the embedded default input.

``source.path`` empty (``type: file``) means the embedded demo input: the real squat video of the shared test
data (tfjs-models' ``pose_squats.mp4``) when it is there, else a landmark recording the project generates
(``bench.simulate``'s squat sequence) in the cache dir.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path

from posed.daemon.config import Config
from posed.daemon.config.load import key_covers
from posed.hal import file_problem, is_landmark_recording

ROOT = Path(__file__).resolve().parent.parent
SQUAT_VIDEO = Path("reference") / "tfjs_pose_squats" / "pose_squats.mp4"


def shared_data() -> Path:
    return Path(os.environ.get("POSED_SHARED_DATA", ROOT.parent / "shared" / "data"))


def cache_dir() -> Path:
    base = os.environ.get("CACHE_DIRECTORY") or os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base.split(":")[0]) / "posed"


def default_input(make_recording: Callable[[Path], Path]) -> Path:
    """The embedded demo input: the real squat video if present, else the landmark recording that
    ``make_recording(path)`` writes (the CLI passes ``bench.demo_recording.ensure_demo_recording``: the
    daemon itself never loads the offline package)."""
    video = shared_data() / SQUAT_VIDEO
    if video.is_file():
        return video
    return make_recording(cache_dir() / "demo_squats.landmarks.jsonl")


def resolve_source(cfg: Config, make_recording: Callable[[Path], Path]) -> Config:
    """``cfg`` with an empty file path replaced by the embedded demo input, and a URI query left in the path
    (``file:PATH?loop=true`` as ``--source`` gives it) moved into the source keys, so that the stage plan sees
    the file's real name (a ``*.landmarks.jsonl`` replay skips the camera stages). A bad query is left for
    :func:`check` to report."""
    if cfg.source.type != "file":
        return cfg
    if not cfg.source.path:
        return dataclasses.replace(cfg, source=dataclasses.replace(cfg.source,
                                                                   path=str(default_input(make_recording))))
    if "?" in cfg.source.path and not Path(cfg.source.path).exists():
        problems: list[str] = []
        src = _without_query(cfg.source, problems)
        if not problems:
            return dataclasses.replace(cfg, source=src)
    return cfg


def _without_query(src, problems: list[str]):
    """The source config with a URI query (``?loop=true&realtime=false``) moved out of its path into its keys,
    as the capture stage reads it (hal.parse_uri); a bad query is a problem."""
    from posed.hal import SourceError, parse_uri

    try:
        return parse_uri(f"file:{src.path}", base=src)
    except SourceError as exc:
        problems.append(f"source: {exc}")
        return src


def check(cfg: Config) -> list[str]:
    """Every problem that would stop the daemon (or make a stage fail over and over), each naming the key and
    what to change. ``posed config check`` and ``posed run`` (before any stage is spawned) both run it.

    Checked: the source file (an empty ``source.path`` is the embedded demo input, resolved by ``posed run``),
    the native Zenoh config (readable, and valid for Zenoh), the landmark models (present and matching their
    manifest's sha256; not needed for a ``*.landmarks.jsonl`` source), the calibration file and every hook's
    argv (keys wrong between themselves, such as ``fitting.row_init`` above ``row_max``, are the config
    loader's: ``daemon.config.schema.cross_problems``)."""
    problems: list[str] = []
    src = cfg.source
    if src.type == "file" and "?" in src.path and not Path(src.path).exists():
        src = _without_query(src, problems)      # file:PATH?loop=true, as --source gives it
    if src.type == "file" and src.path and not Path(src.path).exists():
        problems.append(f"source.path: {src.path} does not exist; give a video, an image folder, a RealSense "
                        "recording or a .landmarks.jsonl (or --source file:PATH)")
    elif src.type == "file" and src.path and (problem := file_problem(src.path)):
        problems.append(f"source.path: {problem}")
    problems += _zenoh_problems(cfg)
    recording = src.type == "file" and bool(src.path) and is_landmark_recording(src.path)
    if not recording:
        problems += _model_problems(cfg)
    elif src.has_faults:
        problems.append("source: the test faults (drop, stall_at, disconnect_at, corrupt_at: source.fault_*) act "
                        "on camera frames, and a .landmarks.jsonl replay has none, so they would do nothing; "
                        "replay the video the recording came from, or remove them")
    if cfg.fitting.calibration:
        problems += calibration_problems(cfg.fitting.calibration)
    for key, i, hook in _hooks(cfg):
        if not hook.argv or not hook.argv[0]:
            problems.append(f"hooks.{key}[{i}].argv is empty; give a program and its arguments as a list, "
                            'e.g. argv: ["/usr/local/bin/notify", "--fall"]')
    return problems


def _hooks(cfg: Config):
    """(list key, index, hook) of every configured hook: fall events', posed not watching's and the person not
    seen's."""
    for key in ("on_event", "on_watch_lost", "on_absent"):
        for i, hook in enumerate(getattr(cfg.hooks, key)):
            yield key, i, hook


def partial_problems(exc) -> list[str]:
    """The start-up checks (``check`` and the hook programs) on the config a ``ConfigError`` read as far as it
    could (``exc.partial``), so that a config with a wrong key still has its missing model, calibration file
    or hook program listed in the same run. A check of a key the error already names (or of one inside a
    section it names) is left out: that key was replaced by its default, and its check would be about the
    default."""
    cfg = getattr(exc, "partial", None)
    if cfg is None:
        return []
    named = [p.path for p in exc.problems if p.path]

    def covered(problem: str) -> bool:
        key = problem.split(":", 1)[0].split(" ", 1)[0]
        return any(key_covers(key, n) for n in named)

    try:
        found = check(cfg) + hook_program_problems(cfg) + model_provenance_problems(cfg)
    except Exception:       # a check that cannot run on a half-read config: the schema's problems stand
        return []
    return [p for p in found if not covered(p)]


def calibration_problems(path: str) -> list[str]:
    """What is wrong with the calibration file ``path`` (read with a bound: a huge file or /dev/zero is an
    error, not a hang), as ``fitting.calibration:`` lines."""
    from posed.fitting import CalibrationError, read_calibration

    try:
        read_calibration(path)
    except CalibrationError as exc:
        return [f"fitting.calibration: {exc}"]
    return []


def _zenoh_problems(cfg: Config) -> list[str]:
    path = cfg.zenoh.config_file
    if not path:
        return []
    p = Path(path)
    if not p.is_file():
        what = "is a folder" if p.is_dir() else "does not exist"
        return [f"zenoh.config_file: {path} {what}; give a Zenoh JSON5 config file or leave it empty"]
    try:
        with open(p, "rb"):
            pass
    except OSError as exc:
        return [f"zenoh.config_file: {path} cannot be read ({exc.strerror}); make it readable by the daemon's "
                "user or leave the key empty"]
    from posed.daemon.bus.session import ZenohConfigError, build_config

    try:
        build_config(cfg.zenoh)
    except ZenohConfigError as exc:
        return [" ".join(str(exc).split())]           # zenoh's message spans lines: one line per problem
    return []


def _model_problems(cfg: Config) -> list[str]:
    from posed.landmarks import ModelMissingError, find_models, verify_models

    try:
        verify_models(find_models(cfg.landmarks.models_dir or None))
    except (ModelMissingError, ValueError, OSError) as exc:     # ModelCorruptError: damaged or unreadable
        text = str(exc)
        if "posed models fetch" not in text:
            text += "; run: posed models fetch"
        return [f"landmarks: {text}"]
    return []


def model_provenance_problems(cfg: Config) -> list[str]:
    """Intact landmark models that are not the ones this posed runs (an earlier posed's converter, another
    mediapipe release's files: ``landmarks.check_provenance``). Not a reason to stop watching: ``posed config
    check`` lists it (exit 78), ``posed run`` logs it and starts on them; ``posed models fetch`` fixes it.
    Empty for a landmark recording (no models run) and for models ``check`` already reports as missing."""
    from posed.landmarks import ModelMissingError, ModelOutdatedError, check_provenance, find_models

    src = cfg.source
    if src.type == "file" and src.path and is_landmark_recording(src.path.split("?", 1)[0]):
        return []
    try:
        paths = find_models(cfg.landmarks.models_dir or None)
        check_provenance(paths)
    except ModelOutdatedError as exc:
        return [f"landmarks: {exc}"]
    except (ModelMissingError, ValueError, OSError):      # missing or damaged: check() says so
        return []
    return []


def hook_program_problems(cfg: Config) -> list[str]:
    """Hooks whose program does not exist or is not executable (as the publisher would start it: an absolute
    or relative path as given, a bare name through PATH). Not a reason to stop detection: ``posed config check``
    lists them (exit 78), ``posed run`` logs them and starts; such a hook would fail at the first fall."""
    import shutil

    problems = []
    for key, i, hook in _hooks(cfg):
        if not hook.argv or not hook.argv[0]:
            continue                                  # check() reports an empty argv
        prog = hook.argv[0]
        found = Path(prog) if os.sep in prog else shutil.which(prog)
        when = {"on_event": "at the first fall", "on_absent": "when the person is not seen for longer than "
                "usual"}.get(key, "when posed stops watching")
        if found is None or not Path(found).is_file():
            problems.append(f"hooks.{key}[{i}].argv[0]: {prog!r} does not exist"
                            + ("" if os.sep in prog else " on PATH") + "; give the absolute path of an installed "
                            f"program (the hook would fail {when})")
        elif not os.access(found, os.X_OK):
            problems.append(f"hooks.{key}[{i}].argv[0]: {found} is not executable; chmod +x it or give the "
                            "program that runs it (e.g. argv: [/usr/bin/python3, script.py])")
    return problems

