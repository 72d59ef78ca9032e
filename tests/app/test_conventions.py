"""Command-line conventions: ``python -m sinslab``, ``--version`` with the numerical
packages' versions, and tab completion of commands and experiment names."""
import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path

from sinslab import __version__

ROOT = Path(__file__).resolve().parents[2]


def _sinslab(*args, env=None, cwd=None):
    return subprocess.run([sys.executable, "-m", "sinslab", *args], capture_output=True, text=True,
                          env=dict(os.environ, **(env or {})), cwd=cwd, timeout=120)


def test_python_m_sinslab_is_the_command_line(tmp_path):
    r = _sinslab("--version", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    want = (f"sinslab {__version__} (numpy {metadata.version('numpy')}, numba {metadata.version('numba')}, "
            f"Python {sys.version.split()[0]})")
    assert r.stdout.strip() == want
    r = _sinslab(cwd=tmp_path)                         # alone: the help page, exit 0
    assert r.returncode == 0 and "Commands" in r.stdout and "list" in r.stdout


def test_version_is_written_once():
    """pyproject.toml takes the version from sinslab/__init__.py; the installed metadata
    agrees with it."""
    text = (ROOT / "pyproject.toml").read_text()
    assert 'dynamic = ["version"]' in text and "\nversion =" not in text.split("[project.urls]")[0]
    assert metadata.version("sinslab") == __version__


def test_shell_completion_script_and_candidates(tmp_path):
    r = _sinslab("--show-completion", "bash", cwd=tmp_path)
    assert r.returncode == 0 and "complete" in r.stdout and "_SINSLAB_COMPLETE" in r.stdout.upper()

    def complete(words: str, cword: int) -> list[str]:
        # what the installed bash script asks the program (prog name as the script uses it)
        r = subprocess.run([sys.executable, "-c", "from sinslab.cli import main; main()"],
                           env=dict(os.environ, _SINSLAB_COMPLETE="complete_bash", COMP_WORDS=words,
                                    COMP_CWORD=str(cword)),
                           capture_output=True, text=True, cwd=tmp_path, timeout=120)
        assert r.returncode == 0, r.stderr
        return r.stdout.split()

    assert complete("sinslab na", 1) == ["navigate"]
    assert complete("sinslab run free", 2) == ["free-inertial"]
    assert "--quick" in complete("sinslab config static-alignment --q", 3)
