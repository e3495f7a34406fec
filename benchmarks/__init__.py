"""Commands that print figures (speed, load, device loop, dashboard); run from the repository root with
``.venv/bin/python -m benchmarks NAME``. Not part of the installed package, and not tests: the test suite asserts
behaviour, these measure it (docs/results.md records their output)."""
