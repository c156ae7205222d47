"""`mtlc lint`: everything `mtlc check` reports plus motion rules, over a population of
manikins, for CI (text, JSON, GitHub annotations, SARIF). See docs/lint.md."""

from mtlc.lint.config import ConfigError, LintConfig, load_config
from mtlc.lint.engine import LintResult, lint_paths
from mtlc.lint.findings import Finding

__all__ = ["ConfigError", "Finding", "LintConfig", "LintResult", "lint_paths", "load_config"]
