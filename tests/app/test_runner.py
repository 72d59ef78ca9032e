"""app/errors (one line, exit 2) and the recorded-data command runner."""
import json

import pytest
import typer

from sinslab.app.commands.runner import Command, Output, Series, cli_call, run_command
from sinslab.app.errors import CliError, UserError, user_errors
from sinslab.app.outputs import OutputDirError

CMD = Command("demo-cmd", "a test command")


def test_user_error_is_one_line_and_exit_2(capsys):
    with pytest.raises(typer.Exit) as ei:
        with user_errors():
            raise CliError("first line\nsecond line")
    assert ei.value.exit_code == 2
    assert capsys.readouterr().err == "sinslab: error: first line\n"


def test_unknown_experiment_is_a_user_error():
    from sinslab.experiments import UnknownExperiment

    assert issubclass(UnknownExperiment, UserError) and issubclass(UnknownExperiment, KeyError)


def test_interrupt_is_exit_130(capsys):
    with pytest.raises(typer.Exit) as ei:
        with user_errors():
            raise KeyboardInterrupt
    assert ei.value.exit_code == 130 and "interrupted" in capsys.readouterr().err


def test_runner_writes_the_folder_in_order(tmp_path):
    out = tmp_path / "r"
    summary, res = run_command(CMD, out, lambda: Output(
        config={"file": "x.csv"}, metrics={"a": 1.5}, tables=[Series("t", {"x": [1, 2]})],
        files={"extra.toml": "k = 1\n"}, notes=["n"], value=7), echo=lambda m: None)
    assert res.value == 7 and summary["metrics"] == {"a": 1.5}
    for f in ("config.toml", "extra.toml", "t.csv", "summary.json", "report.html"):
        assert (out / f).is_file()
    assert json.loads((out / "summary.json").read_text())["experiment"] == "demo-cmd"
    assert (out / "config.toml").read_text().startswith("# sinslab ")


def test_runner_checks_the_folder_before_computing(tmp_path):
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "mine.txt").write_text("x")
    called = []
    with pytest.raises(OutputDirError):
        run_command(CMD, tmp_path / "busy", lambda: called.append(1))
    assert not called


def test_cli_call_turns_bad_values_into_exit_2_with_nothing_written(tmp_path, capsys):
    def bad(out):
        return run_command(CMD, out, lambda: (_ for _ in ()).throw(ValueError("--x: bad")))

    with pytest.raises(typer.Exit) as ei:
        cli_call(bad, tmp_path / "o")
    assert ei.value.exit_code == 2 and capsys.readouterr().err == "sinslab: error: --x: bad\n"
    assert not (tmp_path / "o").exists()
