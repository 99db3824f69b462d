"""In the dark: posed's landmark stage on colour images in dim light and on grayscale (infrared-like) images.

Real videos and images of the shared data (bench/night.py) under a camera-sensor model of less light (the
RealSense D435's colour sensor, bench/night_sensor.py), as grayscale, and as grayscale with the projector's
dots, each through the landmark stage as the daemon runs it. Per source and condition: the frames where the
person the colour original found is still found, the 12 body landmarks' deviation from the original (px and
over the torso length), the median mean luma; and the mean luma below which colour stops finding people
(found rate under 95 % and 80 % of the original): the evidence for the night mode's switch to infrared. The
``+gain`` conditions run the same dim frames brightened by a gain first (``bench.night_gain``: measured, not adopted).

Run: ``posed bench night [--json] [--quick N] [--seed S] [--sources dev|untouched]`` (about 17 minutes on 2
cores; ``--quick 6``: the first 6 frames of the squat video only; ``--sources untouched``: the multi-person
clips, never looked at while the gain was made).
"""

from __future__ import annotations

import argparse
import json
import sys

from posed.commands import add_config_args, config_from_args


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", type=int, metavar="N", default=None,
                        help="only the first N frames of the squat video (a small run, for tests)")
    parser.add_argument("--seed", type=int, default=None, help="the seed of the noise and dots (default fixed)")
    parser.add_argument("--sources", choices=("dev", "untouched"), default="dev",
                        help="dev: the squat video, pose2sim's four views and three images (default); untouched: "
                             "the multi-person clips s2d_enter and bend_hand")
    parser.add_argument("--only", metavar="NAMES", default=None,
                        help="run only these conditions, comma-separated (and the original); each on the frames "
                             "it draws in the whole run")
    add_config_args(parser, source=False, example="landmarks.max_people=1")


def run(args: argparse.Namespace) -> int:
    from posed.bench import night  # not at import: `posed bench` lists this module
    from posed.daemon.preflight import shared_data
    from posed.landmarks import ModelMissingError

    config = config_from_args(args)
    shared = shared_data()
    if not shared.is_dir():
        print(f"posed bench night: no shared data at {shared} (set POSED_SHARED_DATA)", file=sys.stderr)
        return 2
    try:
        report = night.run_bench(shared, config, quick=args.quick, seed=night.SEED if args.seed is None else args.seed,
                                 sources=args.sources,
                                 only=None if args.only is None else {n.strip() for n in args.only.split(",")},
                                 progress=lambda m: print(m, file=sys.stderr, flush=True))
    except ModelMissingError as exc:
        print(f"posed bench night: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(report))
    else:
        print("\n".join(night.table(report)))
    return 0
