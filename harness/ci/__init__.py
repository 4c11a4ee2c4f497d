"""Nightly performance CI: :mod:`.baseline` (compare a sweep with the committed baseline,
tolerances, JUnit/Markdown) and :mod:`.history` (the store of every CI run)."""
