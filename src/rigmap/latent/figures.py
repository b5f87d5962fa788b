"""Fig 2 of Bailey et al. 2016: latent spaces with their takes coloured, with and without
the connectivity prior (the first two latent dimensions; ours: the fit without the prior
is refitted here with the same settings otherwise)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rigmap.latent.library import fit_set


def draw_latent_spaces(rig, fitted, without, fps: float, variance, path, *, labels):
    """One row per label: the stage's model (connectivity prior) beside a refit without."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from rigmap.viz.atomic import save_figure

    fig, axes = plt.subplots(len(labels), 2, figsize=(8, 3.6 * len(labels)), squeeze=False)
    for row, label in zip(axes, labels, strict=True):
        entry = fitted.sets[label]
        fraction, n_pca = variance  # (PCA variance fraction, components or None)
        other = fit_set(rig, entry, fps=fps, variance=fraction, n_pca=n_pca, settings=without)
        for ax, model, title in (
            (row[0], fitted.models[label], "with the connectivity prior"),
            (row[1], other, "without it"),
        ):
            X = model.latent
            X2 = X[:, :2] if X.shape[1] > 1 else np.column_stack([X[:, 0], np.zeros(len(X))])
            for k, name in enumerate(entry.names):
                rows = entry.rows(name)
                ax.plot(*X2[rows].T, "-o", ms=2, lw=0.8, color=f"C{k}", label=name)
            ax.set_title(f"{label}: {title}", fontsize=9)
            ax.set_xlabel("x1")
            ax.set_ylabel("x2")
        row[0].legend(fontsize=7)
    fig.suptitle(f"{rig.name}: GPLVM latent spaces, takes coloured (rigmap, cf. Fig 2)")
    fig.tight_layout()
    save_figure(fig, Path(path), dpi=90)
    plt.close(fig)
    return Path(path)
