"""Maintainer tools of the hdjoint project, beside the installed package
hdtools and not part of its wheel: the Cortex-M4 targets under QEMU
(tools/target), the benchmarks (tools/bench) and the document generators
(tools/update-docs).  Run from a checkout with tools/ on sys.path."""
