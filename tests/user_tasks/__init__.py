"""A task written outside the package by the CONTRIBUTING recipe ("Add a task"), for the tests."""
