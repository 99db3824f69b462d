import numpy as np
import pytest

from posed.landmarks.config import LandmarkConfig
from posed.landmarks.models import ModelCorruptError, ModelMissingError
from posed.landmarks.pipeline import PoseLandmarker
from posed.landmarks.runtime import ModelLoadError, OnnxDetector, OnnxLandmarkModel, SessionSettings


def test_models_load_and_give_outputs_in_canonical_shapes(models_dir):
    det = OnnxDetector(models_dir / "pose_detection.onnx", SessionSettings(threads=2))
    lm = OnnxLandmarkModel(models_dir / "pose_landmark_full.onnx")
    assert det.session.get_session_options().intra_op_num_threads == 2
    boxes, scores = det(np.zeros((1, 224, 224, 3), np.float32))
    assert boxes.shape == (2254, 12) and scores.shape == (2254,)
    out = lm(np.zeros((1, 256, 256, 3), np.float32))
    assert out.landmarks.shape == (195,) and out.heatmap.shape == (64, 64, 39) and out.world.shape == (117,)
    assert 0.0 <= out.pose_flag <= 1.0  # already a probability (the model ends with a logistic)
    assert len(lm.session.get_outputs()) == 4  # converted without the segmentation head
    assert all(o.shape != [1, 256, 256, 1] for o in lm.session.get_outputs())


def test_a_corrupt_model_file_is_reported_with_the_fix(tmp_path):
    bad = tmp_path / "pose_landmark_full.onnx"
    bad.write_bytes(b"\x08\x07garbage" * 100)
    with pytest.raises(ModelLoadError) as err:
        OnnxLandmarkModel(bad)
    assert isinstance(err.value, ModelCorruptError)
    assert str(bad) in str(err.value) and "posed models fetch" in str(err.value)


def test_the_wrong_model_is_refused_naming_the_shapes(models_dir):
    with pytest.raises(ModelLoadError, match=r"\[1, 224, 224, 3\].*expected \[1, 256, 256, 3\]"):
        OnnxLandmarkModel(models_dir / "pose_detection.onnx")
    with pytest.raises(ModelLoadError, match=r"\[1, 256, 256, 3\].*expected \[1, 224, 224, 3\]"):
        OnnxDetector(models_dir / "pose_landmark_full.onnx")


def test_missing_models_name_the_fetch_command(tmp_path):
    with pytest.raises(ModelMissingError, match="posed models fetch"):
        PoseLandmarker(LandmarkConfig(), models_dir=tmp_path / "nowhere")
    with pytest.raises(ModelMissingError, match="posed models fetch"):
        OnnxDetector(tmp_path / "pose_detection.onnx")


def test_a_damaged_model_in_the_models_folder_is_caught_before_use(models_dir, tmp_path):
    for f in models_dir.iterdir():
        (tmp_path / f.name).symlink_to(f)
    damaged = tmp_path / "pose_landmark_full.onnx"
    damaged.unlink()
    data = bytearray((models_dir / "pose_landmark_full.onnx").read_bytes())
    data[len(data) // 2] ^= 0xFF
    damaged.write_bytes(bytes(data))
    with pytest.raises(ModelCorruptError, match="pose_landmark_full.onnx.*posed models fetch"):
        PoseLandmarker(LandmarkConfig(), models_dir=tmp_path)
