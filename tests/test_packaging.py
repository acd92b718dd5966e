"""What a packager and a user get: DBCs as package data, "none" in the config, one version, the wheel."""
from __future__ import annotations

import importlib.metadata
import importlib.resources
import os
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

import ecu_daemon
from ecu_daemon import config
from ecu_daemon.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = importlib.resources.files("ecu_daemon") / "dbc"


def test_default_dbcs_are_the_package_data_from_any_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing called dbc/ here
    cfg = config.load(None)
    assert cfg.dbc_path() == Path(str(SHIPPED / "ecu_daemon_inputs.dbc"))
    assert cfg.output_dbc_path() == Path(str(SHIPPED / "ecu_daemon_outputs.dbc"))
    assert cfg.dbc_path().is_file() and cfg.output_dbc_path().is_file()


def test_existing_configs_find_the_shipped_dbc_and_a_users_own_copy_shadows_it(tmp_path):
    etc = tmp_path / "etc"
    etc.mkdir()
    cfg_file = etc / "ecu.toml"
    cfg_file.write_text('[can]\ndbc = "dbc/ecu_daemon_inputs.dbc"\n')
    assert config.load(cfg_file).dbc_path() == Path(str(SHIPPED / "ecu_daemon_inputs.dbc"))
    own = etc / "dbc" / "ecu_daemon_inputs.dbc"
    own.parent.mkdir()
    own.write_bytes((SHIPPED / "ecu_daemon_inputs.dbc").read_bytes())
    assert config.load(cfg_file).dbc_path() == own


def test_a_missing_dbc_is_reported_at_the_path_the_user_wrote(tmp_path):
    cfg_file = tmp_path / "ecu.toml"
    cfg_file.write_text('[can]\ndbc = "dbc/nope.dbc"\n')
    assert config.load(cfg_file).dbc_path() == tmp_path / "dbc" / "nope.dbc"


@pytest.mark.parametrize("word", ["none", "None", "NONE"])
def test_none_in_the_config_turns_state_file_and_gnss_port_off(tmp_path, monkeypatch, word):
    """``state_file = "none"`` once made the daemon write a file called ``none`` into its CWD."""
    cfg_file = tmp_path / "ecu.toml"
    cfg_file.write_text(f'[daemon]\nstate_file = "{word}"\n[gnss]\nport = "{word}"\n')
    cfg = config.load(cfg_file)
    assert cfg.daemon.state_file == "" and cfg.gnss.port == ""
    assert config.load(None).daemon.state_file == "/var/lib/ecu-daemon/state.json"  # not every value


def test_the_version_is_written_once(capsys):
    assert importlib.metadata.version("ecu-daemon") == ecu_daemon.__version__
    with pytest.raises(SystemExit):
        cli_main(["--version"])
    assert capsys.readouterr().out.strip() == f"ecu-daemon {ecu_daemon.__version__}"
    assert "version =" not in (ROOT / "pyproject.toml").read_text().split("[project.optional")[0]


def test_wheel_ships_the_dbcs_and_the_licence_and_no_data_files(tmp_path):
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path), str(ROOT)],
                       capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = tmp_path.glob("ecu_daemon-*.whl")
    names = zipfile.ZipFile(whl).namelist()
    assert {"ecu_daemon/dbc/ecu_daemon_inputs.dbc", "ecu_daemon/dbc/ecu_daemon_outputs.dbc"} <= set(names)
    assert any(n.endswith(".dist-info/LICENSE") or "/licenses/LICENSE" in n for n in names), names
    assert not [n for n in names if ".data/" in n], "setuptools data-files are deprecated: use package data"
    meta = zipfile.ZipFile(whl).read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    requires = [ln.split(":", 1)[1].strip() for ln in meta.splitlines() if ln.startswith("Requires-Dist:")]
    assert "python-can>=4.6" in requires and "crccheck>=1.3" in requires  # imported directly
    # the compiled estimator kernels, frame encoder and CSV rows are built into the wheel (setup.py)
    for mod in ("ecu_daemon/estimator/_kernels.", "ecu_daemon/_frames.", "ecu_daemon/_estimate_csv.",
                "ecu_daemon/_candump."):
        assert [n for n in names if n.startswith(mod) and n.endswith(".so")], (mod, names)


#: a hung build's limit, not a speed target: a full build compiles every Cython module and took 553 s
#: alone at load 14 on this 2-core machine (and timed out at 600 s in a CI run at load 17)
BUILD_TIMEOUT_S = 2400


def test_sdist_carries_the_kernel_sources_and_builds_them(tmp_path):
    """A user installing from the sdist (no repository) gets the compiled kernels too."""
    sdist_dir, wheel_dir = tmp_path / "sdist", tmp_path / "wheel"
    sdist_dir.mkdir()
    code = f"from setuptools import build_meta; print(build_meta.build_sdist({str(sdist_dir)!r}))"
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
    assert r.returncode == 0, r.stderr[-2000:]
    (sdist,) = sdist_dir.glob("ecu[-_]daemon-*.tar.gz")
    with tarfile.open(sdist) as tf:
        names = {n.split("/", 1)[1] for n in tf.getnames() if "/" in n}
    assert {"setup.py", "ecu_daemon/estimator/_kernels.c", "ecu_daemon/estimator/_generated.h",
            "ecu_daemon/estimator/generated.py", "ecu_daemon/_frames.c", "ecu_daemon/_estimate_csv.c",
            "ecu_daemon/_candump.c"} <= names
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(wheel_dir), str(sdist)],
                       capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = wheel_dir.glob("ecu_daemon-*.whl")
    assert [n for n in zipfile.ZipFile(whl).namelist() if n.startswith("ecu_daemon/estimator/_kernels.")]


#: what a build, an install or a test run leaves in a checkout and .gitignore keeps out
_NOT_SHIPPED = {".git", ".venv", "build", "dist", ".hypothesis", ".pytest_cache", "__pycache__", "out", "work"}


def _tree() -> list[Path]:
    out = []
    for here, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in _NOT_SHIPPED and not d.endswith(".egg-info")]
        out += [Path(here) / f for f in files]
    return out


def test_the_checkout_holds_no_stray_files():
    """Once a kernel test's ``state_file = "none"`` left a file called ``none`` here, and a pyflakes
    wheel was committed; this runs after the kernel tests (tests/kernel sorts first), so a test that
    writes into the checkout is caught too."""
    stray = [str(p.relative_to(ROOT)) for p in _tree()
             if p.name.lower() in ("none", "null", "") or p.suffix in (".whl", ".tar", ".gz") and "data" not in p.parts]
    assert stray == []


def test_one_vendored_copy_of_each_opendbc_file_and_a_licence_beside_the_vendored_data():
    dbcs = [p for p in _tree() if p.suffix == ".dbc" and p.parent.name != "dbc"]  # ecu_daemon/dbc: our own
    names = [p.name for p in dbcs]
    assert names.count("_toyota_2017.dbc") == 1, [str(p) for p in dbcs]
    contents = [p.read_bytes() for p in dbcs]
    assert len(set(contents)) == len(contents), "the same DBC vendored twice"
    assert (ROOT / "LICENSE").is_file() and "MIT License" in (ROOT / "LICENSE").read_text()
    for p in dbcs + [p for p in _tree() if "data" in p.relative_to(ROOT).parts[:2]]:
        if p.name.startswith(("LICENSE", "README")):
            continue
        here = p.parent  # the project's own LICENSE (at the root) does not cover what others wrote
        while here != ROOT and not any(q.name.startswith("LICENSE") for q in here.iterdir()):
            here = here.parent
        assert here != ROOT, f"{p.relative_to(ROOT)}: no LICENSE* of its own beside it or above it"
