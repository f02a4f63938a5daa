"""One module per stage, in the order make runs them (``build.STAGES``): prepare, plan,
init, optimize, solid, fabcheck, export, verify.  Each reads its inputs through the
``build.Build``, calls the library, and writes its artifacts and its JSON report."""
