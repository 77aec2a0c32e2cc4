"""Estimator families, one module each: ``ellipsoid`` (svd, convex), ``mle`` (CasADi/IPOPT),
``exact`` (errors-in-variables ML), ``gradient_descent`` (the paper's baseline), ``sixpos``."""
