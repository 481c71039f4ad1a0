"""Benchmarks (issue 7): accuracy of the filter against peer methods and the
noise floor on simulated and real data, and compute cost on host and target.

Entry point: `tools/bench` (= `hdsense bench`).  Modules:
  peers     independent peer methods (Butterworth, order-domain notch,
            Fourier compensation table) in numpy/scipy
  metrics   RMS error, line attenuation, step delay/settle, recovery time
  accuracy  the simulated scenarios (tests/bench/scenarios) and the methods
  real      the real iiwa logs (residual-based line amplitudes only)
  compute   host benchmark (tests/bench/bench_compute) and target counts
  report    tables, JSON and plot
"""
