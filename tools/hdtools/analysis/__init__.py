"""Closed-loop analysis of measured torque: replay through the C filter,
find what the model lacks, add it, report before/after (`hdsense analyze`).

Modules: loading (CSV / candump -> clean uniform segments), cfilter (ctypes
binding of filter/hd_pipeline.h), model (the filter model and its firmware
config), spectra (order and time spectra, line fits), detect (effects and
their evidence), augment (the add-and-verify loop), report (JSON, Markdown,
plots), bench_speed (one-hour speed benchmark)."""
