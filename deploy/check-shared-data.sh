#!/usr/bin/env bash
# The tests need the real data beside the clone (../shared/data); CI must fail, never skip, without it.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
data=${POSED_SHARED_DATA:-$here/../shared/data}
for f in reference/mediapipe_pose_jpg/pose.jpg reference/tfjs_pose_squats/pose_squats.mp4 \
         reference/mediapipe_samples_ios_sitting/test_image.jpg mocap/cmu/131_01.bvh; do
    if [ ! -f "$data/$f" ]; then
        echo "check-shared-data: missing $data/$f — the tests need ../shared/data beside the clone" >&2
        exit 1
    fi
done
