"""The offline G-code checker (`pkmbench check`): :mod:`.checks` (the checks: plan, geometry,
dynamics), :mod:`.findings` (the model: findings, the report, the exit code, JSON),
:mod:`.text` (the text report)."""
from harness.check.checks import check_program
from harness.check.findings import EXIT_CLEAN, EXIT_FINDINGS, EXIT_INVALID, CheckError, Finding, Report
from harness.check.text import TEXT_LIMIT, as_text

__all__ = ["check_program", "CheckError", "Finding", "Report", "TEXT_LIMIT", "as_text",
           "EXIT_CLEAN", "EXIT_FINDINGS", "EXIT_INVALID"]
