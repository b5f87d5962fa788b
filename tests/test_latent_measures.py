"""The knee of held-out error against the latent dimension (#18, §6) and how the report says it."""

from __future__ import annotations

import pandas as pd

from rigmap.latent.measures import knee_dimension
from rigmap.reports.latent_tables import knee_note


def test_the_knee_is_where_most_of_the_drop_is_made():
    # flat after 3: the knee is 3
    assert knee_dimension({1: 0.05, 2: 0.02, 3: 0.0030, 4: 0.0029, 5: 0.0028}) == 3
    # a steady fall has its knee at the end
    assert knee_dimension({1: 0.048, 2: 0.032, 3: 0.031, 4: 0.025, 5: 0.017}) == 5
    # the scale does not matter, only the shape
    tiny = {q: 1e-4 * e for q, e in {1: 5.0, 2: 0.4, 3: 0.3, 4: 0.1, 5: 0.0}.items()}
    assert knee_dimension(tiny) == 2
    # a worse last fit (local optimum) is still the reference the drop is measured to
    assert knee_dimension({1: 0.045, 2: 0.0385, 3: 0.031, 4: 0.0254, 5: 0.0301}) == 3


def test_the_report_note_names_the_knee_from_the_numbers():
    def table(errors):
        return pd.DataFrame(
            [
                {"label": lab, "latent_dim": q, "surface_rms_cm": e * f}
                for lab, f in (("happy", 1.0), ("roar", 0.5))
                for q, e in errors.items()
            ]
        )

    steady = knee_note(table({1: 0.048, 2: 0.032, 3: 0.031, 4: 0.025, 5: 0.017}))
    assert "0.036, 0.024, 0.023, 0.019, 0.013 cm" in steady
    assert "is at 5, not at 3" in steady
    flat = knee_note(table({1: 0.05, 2: 0.02, 3: 0.003, 4: 0.0029, 5: 0.0028}))
    assert "at 3, as the paper chose" in flat
    assert "Too few" in knee_note(table({1: 0.05, 2: 0.02}))
