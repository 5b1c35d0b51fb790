"""The paper's Table 4 rows of a model's stored arrays: which numbers count as which
module's parameters (:meth:`tghop.TGHop.n_parameters`, ``tghop info``).

Arrays are named ``<part>.<name>`` (:mod:`tghop.modelfile`); the part says the row.
``index.*`` arrays are bookkeeping and are not counted.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GROUPS", "parameter_groups"]

#: Table 4 row of each array-name prefix (``index.*`` arrays are bookkeeping, not parameters).
GROUPS = {
    "hop1": "transform stage 1",
    "hop": "transform stage 2",  # hop2, hop3, ...
    "sdr": "core SDR",
    "ichm_i": "core ICHM (i)",
    "ichm_ii": "core ICHM (ii)",
    "ichm_iii": "core ICHM (iii)",
    "colour": "colour matching (ours)",
    "refine": "refinement (ours)",
    "layout": "coarse layout (ours)",
    "residual": "residual Gaussian (ours)",
}


def _group(name: str):
    part, _, rest = name.partition(".")
    if part == "layout":  # the coarse model's arrays: one row, its bookkeeping excluded
        return None if rest.startswith("index.") else GROUPS["layout"]
    if part == "index":
        return None
    if part in GROUPS:
        return GROUPS[part]
    if part.startswith("hop"):
        return GROUPS["hop"]
    raise KeyError(name)


def parameter_groups(arrays) -> dict:
    """Count the numbers in ``arrays`` (name -> array) per Table 4 row; bookkeeping excluded."""
    counts = {}
    for name, arr in arrays.items():
        group = _group(name)
        if group is not None:
            counts[group] = counts.get(group, 0) + int(np.asarray(arr).size)
    return counts
