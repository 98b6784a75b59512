"""Robust design in an ``ocp`` job (``shared/specs/ocp.md``, "Robust design"; issue 37): the request
models (``params``), the ``robust`` block of the result (``result``), the run (``run``: the design and its
Monte Carlo), and everything a result has: the Monte Carlo's envelope and samples in the result
(``samples``), its plots (``plots``), CSV tables (``tables``) and what a study over k or a sigma charts
(``trade``).  The modules are imported by path; this face stays empty so that the request models load
without the rest."""
