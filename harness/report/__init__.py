"""Reports: the published figures (:mod:`.figures`, REPORT.md from :mod:`.figures_report`)
and the comparison of a sweep (:mod:`.sweep_report`)."""
