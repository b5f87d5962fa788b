"""The GP core shared by the GPR inverse mapping, the edits' GPs and the GPLVM.

Kernels (:mod:`~rigmap.gp.kernels`), pairwise distances (:mod:`~rigmap.gp.distances`),
factorisations and solves (:mod:`~rigmap.gp.solve`) and the marginal likelihood
(:mod:`~rigmap.gp.likelihood`), on numpy and, where a model is differentiated (the
GPLVM), on torch tensors from the same expressions. Each paper's own parts (the GPR's
length-scale search and subsampling, the edits' optimisers and banded combined solve,
the GPLVM's priors and optimisation) stay in their packages and call this one; it
imports none of them.
"""
