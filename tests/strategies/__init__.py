"""Generators of test inputs shared by the tests and the benches (bench/motion.py)."""
