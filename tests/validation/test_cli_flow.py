"""``synptv flow``: JSON contents against the prescribed values, and bad input."""

import json

import pytest

from validation.cli import main


def test_flow_json_reports_prescribed_and_realized_statistics(capsys):
    status = main(
        [
            "flow",
            "--preset",
            "lem-8hz",
            "--particles",
            "600",
            "--snapshots",
            "60",
            "--modes",
            "80",
            "--json",
            "--quiet",
        ]
    )
    assert status == 0
    out = json.loads(capsys.readouterr().out)
    p = out["prescribed"]
    assert p["u_rms"] == 0.15 and p["epsilon"] == 0.09
    assert p["eta"] == pytest.approx((1e-18 / 0.09) ** 0.25)
    assert p["tau_eta"] == pytest.approx((1e-6 / 0.09) ** 0.5)
    assert p["R_lambda"] == pytest.approx(290.5, abs=0.1)
    realized = out["realized"]
    assert realized["u_rms"] == pytest.approx(0.15, abs=4 * realized["u_rms_stderr"])
    assert 0 <= realized["s2_max_rel_err"] < 0.2  # a small sample: noise, not bias
    assert len(out["s2"]["r"]) == len(out["s2"]["exact_dll"])


def test_flow_from_u_rms_and_epsilon(capsys):
    status = main(
        [
            "flow",
            "--u-rms",
            "0.1",
            "--epsilon",
            "0.05",
            "--particles",
            "200",
            "--snapshots",
            "5",
            "--modes",
            "40",
            "--quiet",
        ]
    )
    assert status == 0
    assert "u' = 0.1 m/s" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--preset", "lem-9hz"], "unknown flow preset 'lem-9hz'"),
        (["--u-rms", "0.1", "--epsilon", "0"], "epsilon must be"),
        (["--u-rms", "0.1", "--epsilon", "0.1", "--nu", "-1"], "nu must be"),
        (["--u-rms", "0.1"], "give both --u-rms and --epsilon"),
        (["--modes", "1"], "n_modes must be"),
        (["--particles", "0"], "argument --particles: must be an integer >= 1, got 0"),
    ],
)
def test_bad_input_exits_2_with_one_line(capsys, args, message):
    assert main(["flow", "--quiet", *args]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1


def test_ctrl_c_is_one_line_and_exit_130(capsys, monkeypatch):
    import validation.commands.flow

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(validation.commands.flow, "summarize_flow", interrupted)
    assert main(["flow", "--quiet"]) == 130
    err = capsys.readouterr().err
    assert err == "synptv flow: interrupted\n"  # one line: no blank line before it in a log


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["run", "--seed", "-1"], "synptv run: error: argument --seed: must be an integer >= 0"),
        (["scene", "--particles", "-5"], "argument --particles: must be an integer >= 0, got -5"),
        (["render", "--frames", "two"], "argument --frames: must be an integer, got 'two'"),
        (["ptv", "--snapshots", "0"], "argument --snapshots: must be an integer >= 1, got 0"),
        (["nosuch"], "synptv: error: argument command: invalid choice: 'nosuch'"),
    ],
)
def test_bad_command_lines_are_one_line_naming_the_option(capsys, argv, message):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1
