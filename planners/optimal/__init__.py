"""``optimal`` (the yardstick, planner.py) and the references beside it: ``copp`` (copp.py),
``toppra`` (toppra.py); the TOPP3-SOCP engine they share (topp3.py), its last resort's time
stretches (timewarp.py) and the IPOPT polish (nlp.py). Nothing is imported here: a planner that
uses only the engine (pso_socp) does not depend on the yardstick's own code (its corpus rows are
keyed by the code they import, harness.corpus.journal)."""
