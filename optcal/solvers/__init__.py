"""Layer 2, solver plumbing: the one place where CasADi NLP solvers are built and cached."""
