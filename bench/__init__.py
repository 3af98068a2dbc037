"""The benches: one script per figure (``docs/figures.md`` says which wrote what).

Each runs from the repository root either way, in the venv of the tests' install
(``pip install -e '.[test]'``): ``python bench/NAME.py [options]`` or ``python -m bench.NAME
[options]``. The scripts import only ``tileviz`` (what they share with the tests is
``tileviz.testing``) and third-party packages, never each other, so neither form needs a path
set up.
"""
