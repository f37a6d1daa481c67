"""Test programs: the text format, its errors, and a run showing hysteresis."""

import numpy as np
import pytest

from rheometer import HYSTERESIS_PROGRAM, Step, parse_program, run_program
from rheometer.transient import DEFAULT_MAX_TIME


def test_every_line_form_parses():
    prog = parse_program("""
        # a comment line
        start from steady stress 2 kPa
        shear at 10 1/s for 60 s          # trailing comment
        shear at 0.5 /s until strain 250%
        stress 5 Pa until strain 10 within 2 min
        Stress 300 mPa for 1.5 min
        rest for 100 ms
        ramp rate from 0.1 to 100 1/s over 60 s
        ramp stress from 1 to 3 kPa over 1 h linear
        """)
    assert prog.start.kind == "stress" and prog.start.value == 2000.0
    s = prog.steps
    assert (s[0].control, s[0].start, s[0].duration) == ("rate", 10.0, 60.0)
    assert (s[1].start, s[1].strain, s[1].duration, s[1].max_time) == (0.5, 2.5, None,
                                                                         DEFAULT_MAX_TIME)
    assert (s[2].control, s[2].start, s[2].strain, s[2].max_time) == ("stress", 5.0, 10.0, 120.0)
    assert (s[3].start, s[3].duration) == (0.3, 90.0)
    assert (s[4].control, s[4].start, s[4].duration) == ("rate", 0.0, 0.1)
    assert (s[5].ramp, s[5].start, s[5].end, s[5].duration) == ("log", 0.1, 100.0, 60.0)
    assert (s[6].control, s[6].ramp, s[6].start, s[6].end, s[6].duration) == (
        "stress", "linear", 1e3, 3e3, 3600.0)
    assert all(isinstance(x, Step) for x in s)


@pytest.mark.parametrize("text, match", [
    ("shear at 10 1/s for 60 s\nspin at 3 rpm", r"program line 2: unknown step 'spin'"),
    ("shear at 10 for 60 s", r"program line 1: cannot read .*expected 'shear at <rate> 1/s"),
    ("rest 100 s", r"program line 1: cannot read 'rest 100 s'; expected 'rest for <time> s'"),
    ("ramp rate from 0 to 10 1/s over 5 s", r"program line 1: a log ramp needs positive"),
    ("ramp rate from 1 to 10 Pa over 5 s", r"program line 1: a rate ramp needs 1/s"),
    ("stress 5 mpa for 1 s", r"program line 1: stress unit 'mpa' is ambiguous"),
    ("shear at 1 1/s for 1 s\nstart at rest", r"program line 2: 'start' must come before"),
    ("# nothing\n\n", r"the program has no steps"),
    ("shear at 1 1/s until strain 0", r"program line 1: step strain"),
])
def test_parse_errors_name_the_line_and_what_was_expected(text, match):
    with pytest.raises(ValueError, match=match):
        parse_program(text)


def test_rate_sweep_up_and_down_shows_hysteresis():
    """Structure lags the rate: on the way down f (and the stress) stay higher at equal rate."""
    df = run_program("hermes2016", 0.46, HYSTERESIS_PROGRAM, G=1e4, K0=1.0, points=200)
    up, down = df[df["step"] == 1], df[df["step"] == 2]
    rates = np.geomspace(0.05, 5.0, 9)
    order = np.argsort(down["shear_rate_per_s"].to_numpy())
    s_up = np.interp(np.log(rates), np.log(up["shear_rate_per_s"]), up["shear_stress_Pa"])
    s_down = np.interp(np.log(rates), np.log(down["shear_rate_per_s"].to_numpy()[order]),
                       down["shear_stress_Pa"].to_numpy()[order])
    assert np.all(s_down >= s_up * (1 - 1e-9))
    assert np.max(s_down / s_up) > 2.0                 # a wide loop around the DST rate
    rest = df[df["step"] == 3]
    assert np.all(rest["shear_rate_per_s"] == 0.0)
    assert rest["shear_stress_Pa"].iloc[-1] < 1e-6 * rest["shear_stress_Pa"].iloc[0]


def test_program_from_steady_start_and_strain_step():
    df = run_program("hermes2016", 0.50, "start from steady rate 0.2 1/s\n"
                     "shear at 0.2 1/s until strain 4\nrest for 1 s", G=1e4, K0=1.0)
    first = df[df["step"] == 1]
    assert first["granular_shear_stress_Pa"].std() < 1e-6 * first["granular_shear_stress_Pa"].mean()
    assert first["time_s"].iloc[-1] == pytest.approx(20.0, rel=1e-8)
    assert df.attrs["start"].startswith("rate")


def test_start_from_rate_above_dst_is_refused():
    with pytest.raises(ValueError, match="no stable steady state"):
        run_program("hermes2016", 0.52, "start from steady rate 5 1/s\nrest for 1 s")
