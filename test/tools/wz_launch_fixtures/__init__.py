"""Tiny node modules for the launcher tests (run with PYTHONPATH=test/tools)."""
