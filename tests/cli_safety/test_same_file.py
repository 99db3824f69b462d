"""An output that is an input is refused before anything is opened for writing (exit 2, both named), in every
command that takes an input and -o: the same path, a symlink to it and a hard link of it."""

from __future__ import annotations

import os
import shutil

from posed.cli import main
from tests.cli_safety.conftest import posed


def _refused(capsys, argv: list[str], output, inputs) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "is the same file as" in err and str(output) in err, err
    assert any(str(p) in err for p in inputs), err
    assert "Traceback" not in err


def test_fit_refuses_the_recording_as_output(tiny, tmp_path, capsys):
    same = tmp_path / "same.jsonl"
    shutil.copy(tiny, same)
    before = same.read_bytes()
    _refused(capsys, ["fit", str(same), "-o", str(same)], same, [same])
    hard = tmp_path / "hard.jsonl"
    os.link(same, hard)
    _refused(capsys, ["fit", str(same), "-o", str(hard)], hard, [same])
    link = tmp_path / "link.jsonl"
    link.symlink_to(same)
    _refused(capsys, ["fit", str(link), "-o", str(same)], same, [link])
    assert same.read_bytes() == before                   # never truncated


def test_calibrate_refuses_the_recording_as_output(tiny, tmp_path, capsys):
    same = tmp_path / "same2.jsonl"
    shutil.copy(tiny, same)
    before = same.read_bytes()
    _refused(capsys, ["calibrate", str(same), "-o", str(same)], same, [same])
    assert same.read_bytes() == before


def test_history_refuses_the_database_as_output(history_db, capsys):
    before = history_db.read_bytes()
    _refused(capsys, ["history", "--db", str(history_db), "--csv", "-o", str(history_db)], history_db, [history_db])
    assert history_db.read_bytes() == before


def test_plot_fit_refuses_its_input_as_output(fit_file, tmp_path, capsys):
    png = tmp_path / "fit.png"
    shutil.copy(fit_file, png)
    before = png.read_bytes()
    _refused(capsys, ["plot", "fit", str(png), "-o", str(png)], png, [png])
    assert png.read_bytes() == before


def test_landmarks_refuses_the_image_as_output(shared_data, tmp_path):
    image = tmp_path / "same.jpg"
    shutil.copy(shared_data / "reference" / "mediapipe_pose_jpg" / "pose.jpg", image)
    before = image.read_bytes()
    r = posed("landmarks", str(image), "-o", str(image))
    assert r.returncode == 2, r.stderr
    assert f"the output {image} is the same file as the input {image}" in r.stderr
    folder = tmp_path / "folder"
    folder.mkdir()
    shutil.copy(image, folder / "a.jpg")
    r = posed("landmarks", str(folder), "-o", str(folder / "a.jpg"))
    assert r.returncode == 2 and "is the same file as the image in the input folder" in r.stderr, r.stderr
    assert image.read_bytes() == before == (folder / "a.jpg").read_bytes()
