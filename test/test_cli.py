"""The ``workzone-ros`` entry point: dispatch and errors."""
from workzone_ros import cli
from workzone_ros.tools import evaluate, train


def test_help_lists_every_subcommand(capsys):
    assert cli.main(['--help']) == 0
    out = capsys.readouterr().out
    for name in cli.SUBCOMMANDS:
        assert name in out


def test_unknown_subcommand_is_a_usage_error(capsys):
    assert cli.main(['frobnicate']) == 2
    assert "unknown subcommand 'frobnicate'" in capsys.readouterr().err


def test_unknown_trainer_and_stage(capsys):
    assert train.main(['nope']) == 2
    assert evaluate.main(['nope']) == 2
    err = capsys.readouterr().err
    assert "unknown model 'nope'" in err and "unknown stage 'nope'" in err
