"""Glint's benchmark: ``python -m bench`` (see ``bench.__main__`` and ``bench.suite``).

Dev-only: needs the project's environment plus bench/requirements.txt (matplotlib, for the
plots; without it the table is still printed).  Output goes to bench/out/ (git-ignored).
"""
