"""``posed models fetch|verify|where``: the landmark models (MediaPipe BlazePose, converted to ONNX)."""

from __future__ import annotations

import argparse
import json
import sys
import time

from posed.commands import add_config_args, config_from_args


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("models", help="fetch, convert and check the landmark models")
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)

    fetch = actions.add_parser(
        "fetch", help="download MediaPipe's pose models (mediapipe 0.10.21 wheel), verify and convert them "
                      "to ONNX; does nothing when the models folder is already complete")
    _common(fetch)
    fetch.add_argument("--from", dest="source", metavar="PATH",
                       help="offline install: a mediapipe-0.10.21 wheel, or a folder holding it or "
                            "pose_detection.tflite and pose_landmark_full.tflite")
    fetch.add_argument("--force", action="store_true", help="convert again even when everything is in place (no download when the kept "
                            "TFLite files match their pins)")
    fetch.set_defaults(func=_fetch)

    verify = actions.add_parser("verify",
                                help="check every model file against manifest.json (exit 0 = intact)")
    _common(verify)
    verify.set_defaults(func=_verify)

    where = actions.add_parser("where", help="print the models folder in use")
    _common(where)
    where.set_defaults(func=_where)


def _common(parser: argparse.ArgumentParser) -> None:
    add_config_args(parser, source=False, example="landmarks.models_dir=/var/lib/posed/models")
    parser.add_argument("--models-dir", metavar="DIR",
                        help="models folder (default: landmarks.models_dir, else $POSED_MODELS_DIR, "
                             "else $XDG_CACHE_HOME/posed/models)")


def _models_dir(args: argparse.Namespace):
    from posed.landmarks import default_models_dir

    if args.models_dir:
        return default_models_dir(args.models_dir)
    return default_models_dir(config_from_args(args).landmarks.models_dir)


def _fetch(args: argparse.Namespace) -> int:
    try:
        from posed.landmarks.convert import FetchError, fetch_models
    except ImportError as exc:  # a runtime-only install lacks the converter's tflite/onnx packages
        missing = exc.name or str(exc)
        print(f"posed models fetch: the converter needs the Python package {missing!r}, part of posed's "
              f"`convert` extra: run `{sys.executable} -m pip install 'posed[convert]'` (from a wheel: "
              "`pip install 'posed-VERSION-py3-none-any.whl[convert]'`), or copy a models folder made elsewhere "
              "(posed models where)", file=sys.stderr)
        return 69

    models_dir = _models_dir(args)
    t0 = time.perf_counter()
    try:
        result = fetch_models(models_dir, source=args.source, force=args.force,
                              say=lambda msg: print(f"posed models: {msg}", flush=True))
    except FetchError as exc:
        print(f"posed models fetch: {exc}", file=sys.stderr)
        return exc.exit_code
    if not result.changed:
        print(f"posed models: up to date in {result.models_dir} ({time.perf_counter() - t0:.2f} s, "
              "nothing to do)")
        return 0
    for name, entry in result.manifest["files"].items():
        print(f"  {name:28s} {entry['bytes']:>10d} B  sha256 {entry['sha256']}")
    print(f"posed models: ready in {result.models_dir} ({result.seconds['total']:.1f} s)")
    return 0


def _verify(args: argparse.Namespace) -> int:
    from posed.landmarks import (
        ModelMissingError,
        check_provenance,
        describe_models,
        find_models,
        installed_models,
        verify_models,
    )

    try:
        paths = find_models(_models_dir(args))
        manifest = verify_models(paths, include_tflite=True)
        check_provenance(paths, manifest)      # intact, and what this posed runs
    except ModelMissingError as exc:           # ModelCorruptError, ModelOutdatedError alike
        print(f"posed models verify: {exc}", file=sys.stderr)
        return 1
    print(f"posed models: intact: {describe_models(installed_models(paths.models_dir))} "
          f"(source {json.dumps(manifest.get('source'))})")
    return 0


def _where(args: argparse.Namespace) -> int:
    print(_models_dir(args))
    return 0
