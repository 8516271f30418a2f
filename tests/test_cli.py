"""The command line and import hygiene."""

import json
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from jaxmotion import __version__
from jaxmotion.cli import main


def test_import_compiles_nothing_and_loads_no_jax():
    code = "import sys, jaxmotion; assert 'jax' not in sys.modules, 'jax imported'; print('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "ok"


def test_help_and_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    assert "scene" in capsys.readouterr().out
    assert main(["version"]) == 0
    assert capsys.readouterr().out.strip() == f"jaxmotion {__version__}"
    assert main([]) == 0  # no command: help, success
    assert "usage" in capsys.readouterr().out


def test_scene_info_and_convert(tmp_path, capsys):
    mesh = trimesh.creation.box(extents=(2.0, 3.0, 1.0))
    path = tmp_path / "room.ply"
    mesh.export(path)
    assert main(["scene", "info", str(path), "--points", "500"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["points"] == 500
    np.testing.assert_allclose(info["bounds_max"], [1.0, 1.5, 0.5], atol=1e-3)
    out = tmp_path / "room.npz"
    assert main(["scene", "convert", str(path), str(out), "--points", "300"]) == 0
    assert "300 points" in capsys.readouterr().out
    assert out.exists()


def test_bad_file_is_one_clear_line(tmp_path, capsys):
    missing = tmp_path / "nope.ply"
    assert main(["scene", "info", str(missing)]) == 2
    err = capsys.readouterr().err
    assert "nope.ply" in err and "Traceback" not in err
