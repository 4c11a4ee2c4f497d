"""`python -m harness.cli` = `pkmbench`."""
import sys

from harness.cli import main

sys.exit(main())
