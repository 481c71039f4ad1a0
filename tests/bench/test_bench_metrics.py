"""The slow-load metric (tools/hdmaint/bench/metrics.load_kept) on signals made
up here, whose share of the load each output keeps is known by construction."""
import numpy as np
import pytest

from hdmaint.bench import metrics

T = np.arange(0.0, 60.0, 1e-3)
# a slow load, and a slow output-locked line (0.3 rad/s output, order 1) that
# the finite record correlates with it by chance
LOAD = 1.2 * np.sin(2 * np.pi * T / 23.0 + 0.4) + 0.8 * np.sin(2 * np.pi * T / 9.0)
RIPPLE = 0.9 * np.cos(0.3 * T + 1.1)


def test_the_line_and_the_load_are_correlated_in_this_record():
    c = np.corrcoef(LOAD, RIPPLE)[0, 1]
    assert abs(c) > 0.05, c   # else the tests below would not tell the regressor's use


@pytest.mark.parametrize("share", [0.0, 0.3, 1.0])
def test_an_output_that_loses_a_share_of_the_load_keeps_the_rest(share):
    # the error of an output that removed the line and `share` of the load
    assert metrics.load_kept(-share * LOAD, LOAD, RIPPLE) == pytest.approx(1.0 - share, abs=1e-9)


@pytest.mark.parametrize("left", [1.0, 0.5])
def test_a_line_left_in_the_output_is_not_counted_on_the_load(left):
    # the raw measurement (left = 1) keeps the load whole, whatever its ripple
    err = left * RIPPLE - 0.2 * LOAD
    assert metrics.load_kept(err, LOAD, RIPPLE) == pytest.approx(0.8, abs=1e-9)


def test_without_the_ripple_regressor_the_line_reads_as_load():
    # why the regressor is there: the one-regressor slope is off by the
    # line's chance correlation with the load
    c = float(np.dot(RIPPLE - RIPPLE.mean(), LOAD - LOAD.mean()) /
              np.dot(LOAD - LOAD.mean(), LOAD - LOAD.mean()))
    assert metrics.load_kept(RIPPLE, LOAD) == pytest.approx(1.0 + c, abs=1e-9)
    assert abs(c) > 0.01
