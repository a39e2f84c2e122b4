"""Benchmarks: each of smafl-jax's speed/accuracy figures next to its baseline, in one run.

``python -m benchmarks [--quick] [--only SECTION ...] [--out DIR] [--docs]``
runs every section module that exists (``bench_<section>.py`` exposing
``run(quick: bool) -> list[dict]`` with rows ``{name, ours, baseline, ratio,
unit}``; optional ``note`` and raw sizes/seconds), skips missing or failing
ones with a note, and writes ``RESULTS.md``, ``results.json`` and
``scaling.png`` (log-log cost vs record length / operator count) atomically.

A row may carry ``scale_series``, ``scale_x``, ``scale_xlabel`` and
``scale_seconds`` to put a point on the scaling plot; a section module may
define ``RATIO_MEANING`` (a short string) to explain its ratio column.
"""
