"""Benchmarks (issue 7): accuracy of the filter against peer methods and the
noise floor on simulated and real data, and compute cost on host and target.

Entry point: `tools/bench` (python -m hdmaint.bench; cli.py).  Modules:
  peers     independent peer methods (Butterworth, order-domain notch,
            Fourier compensation table) in numpy/scipy
  metrics   RMS error, line attenuation, step delay/settle, recovery time
  joint     the simulated joint (hdsim) and the firmware on it (hdjoint-host),
            the firmware's own commissioning of a joint
  accuracy  the simulated scenarios (tests/bench/scenarios) and the methods,
            the product row fw_commissioned among them
  slow      the slow-torque scenarios (tests/bench/scenarios/slow), issue 12
  goals     issue 12's goals checked against the results
  real      the real iiwa logs (residual-based line amplitudes only)
  compute   host benchmark (tests/bench/bench_compute) and target counts
  report    tables, JSON and plot
"""
