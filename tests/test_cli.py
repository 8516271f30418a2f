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


def test_the_command_process_exits_with_main_s_code(tmp_path):
    """``python -m jaxmotion`` (and the ``jaxmotion`` script) end through ``cli.run``: the exit
    code and every line of output are main's, and the exit handlers run (the scratch cache
    of ``JAXMOTION_CACHE=off`` is removed)."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "JAXMOTION_CACHE": "off", "TMPDIR": str(tmp_path)}
    run = lambda *a: subprocess.run([sys.executable, "-m", "jaxmotion", *a], env=env,
                                    capture_output=True, text=True, timeout=120, check=False)
    done = run("version")
    assert done.returncode == 0 and done.stdout.strip() == f"jaxmotion {__version__}"
    done = run("--no-such-option")
    assert done.returncode == 2 and "usage" in done.stderr
    mesh = trimesh.creation.box(extents=(2.0, 3.0, 1.0))
    mesh.export(tmp_path / "room.ply")
    done = run("scene", "info", str(tmp_path / "room.ply"), "--points", "50")
    assert done.returncode == 0 and json.loads(done.stdout)["points"] == 50
    done = run("scene", "info", str(tmp_path / "missing.ply"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    # an error after the scratch cache was made (JAXMOTION_CACHE=off): removed at exit
    done = run("generate", "--scene", "demo", "--object", "999", "--out", str(tmp_path / "o"))
    assert done.returncode == 2 and "unknown object id 999" in done.stderr
    assert not [p for p in tmp_path.iterdir() if p.is_dir()]


def test_scene_info_and_convert(tmp_path, capsys):
    mesh = trimesh.creation.box(extents=(2.0, 3.0, 1.0))
    path = tmp_path / "room.ply"
    mesh.export(path)
    assert main(["scene", "info", str(path), "--points", "500"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["points"] == 500
    # scene info shows the room as generate sees it: its floor (the box's bottom) at z = 0
    np.testing.assert_allclose(info["bounds_max"], [1.0, 1.5, 1.0], atol=1e-3)
    assert any("moved to z = 0" in n for n in info["notes"])
    out = tmp_path / "room.npz"
    assert main(["scene", "convert", str(path), str(out), "--points", "300"]) == 0
    assert "300 points" in capsys.readouterr().out
    assert out.exists()


def test_bad_file_is_one_clear_line(tmp_path, capsys):
    missing = tmp_path / "nope.ply"
    assert main(["scene", "info", str(missing)]) == 2
    err = capsys.readouterr().err
    assert "nope.ply" in err and "Traceback" not in err
