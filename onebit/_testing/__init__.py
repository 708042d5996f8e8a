"""Test oracles and fixtures: never imported by the shipped package (an import-linter contract).

:mod:`onebit._testing.oracles` holds the plain versions of steps that onebit runs another
way (compiled, vectorised or label-table), kept only so the tests and benchmarks can check the
shipped step against them; :mod:`onebit._testing.casas_sim` writes a small CASAS-format log
for the reader and importer tests. A reader of the rest of ``onebit/`` sees one implementation
of each step. (The ``*_reference`` functions still in the package are not oracles only: they
are the step's own path for small inputs, below the size where a compiled kernel pays.)
"""
