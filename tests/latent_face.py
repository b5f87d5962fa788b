"""Small latent models of the face's expression library, fitted once per test session."""

from __future__ import annotations

from functools import lru_cache

from rigmap.latent import GPLVMSettings
from rigmap.latent.library import face_expression_sets, fit_models
from rigmap.latent.transitions import match_models
from rigmap.rigs import load

LABELS = ("happy", "neutral", "roar")


@lru_cache(maxsize=1)
def face_rig():
    return load("face")


@lru_cache(maxsize=1)
def face_models():
    """Three labels, two takes each (~100 frames a label), 6 PCA components, 80 L-BFGS
    iterations (ours: a test-sized fit, a few seconds a model)."""
    rig = face_rig()
    sets = face_expression_sets(rig, labels=LABELS, takes=2)
    return fit_models(rig, sets, n_pca=6, settings=GPLVMSettings(max_iter=80))


@lru_cache(maxsize=1)
def face_transitions():
    return match_models(face_rig(), face_models().models)
