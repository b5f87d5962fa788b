"""What the report's rows are called and in which order they appear.

The keys are the ones the evaluate stages write into metrics file names
(``metrics/<rig>/methods/<method>-<sampler>.json`` ...); the labels are the
paper's (Table 1, Table 2, §7.1) so our tables read side by side with it.
Rows the paper does not have are marked ``extra``.
"""

from __future__ import annotations

from dataclasses import dataclass

from rigmap.rigs.manifest import all_manifests, reported


@dataclass(frozen=True)
class Row:
    """One row kind of a table: metrics key, printed label, and whether the paper has it."""

    key: str
    label: str
    extra: bool = False

    @property
    def display(self) -> str:
        return f"{self.label} (extra)" if self.extra else self.label


METHODS: tuple[Row, ...] = (
    Row("script", "Script"),
    Row("gpr", "GPR"),
    Row("gpr_learned_jacobian", "GPR & Learned Jacobian"),
    Row("gpr_computed_jacobian", "GPR & Computed Jacobian"),
    Row("nn", "NN"),
    Row("nn_computed_jacobian", "NN & Computed Jacobian"),
    Row("nn_learned_jacobian", "NN & Learned Jacobian", extra=True),
    Row("nn_autodiff_jacobian", "NN & Autodiff Jacobian", extra=True),
    Row("nn_joint_space", "Joint-space NN", extra=True),
    Row("nn_joint_space_computed_jacobian", "Joint-space NN & Computed Jacobian", extra=True),
    Row("nn_joint_space_tuned", "Joint-space NN tuned on the clip", extra=True),
    Row("mean", "Mean Predictor", extra=True),
)

SAMPLERS: tuple[Row, ...] = (
    Row("none", "No Extra Samples"),
    Row("uniform", "Uniform"),
    Row("univariate_gaussian", "Univariate Gaussian"),
    Row("multivariate_gaussian", "Multivariate Gaussian"),
    Row("gmm", "Gaussian Mixture Model"),
    Row("pca_gaussian", "PCA & Unit Gaussian"),
)

KERNELS: tuple[Row, ...] = (
    Row("multiquadric", "Multiquadric"),
    Row("gaussian", "Gaussian"),
    Row("linear", "Linear"),
    Row("polynomial", "Polynomial"),
)


def rig_rows() -> tuple[Row, ...]:
    """The reported rigs from their manifests, in the order of the paper's Table 3, then the
    Blender rigs (a rig registered later joins them)."""
    return tuple(Row(m.name, m.label, extra=m.extra) for m in reported())


#: the built-in characters as they stood when this module was imported (see ``rig_rows``)
RIGS: tuple[Row, ...] = rig_rows()


def find_row(rows: tuple[Row, ...], key: str, what: str) -> Row:
    """The row called ``key``; a clear error listing the known keys otherwise."""
    for row in rows:
        if row.key == key:
            return row
    raise KeyError(f"unknown {what} {key!r}; expected one of {[r.key for r in rows]}")


def rig_label(name: str) -> str:
    """``quadruped`` -> ``Quadruped`` (the manifest's label); unknown rigs keep their own name."""
    known = all_manifests().get(name)
    return name if known is None else known.label
