"""The paper's Table 4 rows of a model's stored arrays: which numbers count as which
module's parameters (:meth:`tghop.TGHop.n_parameters`, ``tghop info``).

Arrays are named ``<part>.<name>`` (:mod:`tghop.modelfile`); the part says the row.
``index.*`` arrays are bookkeeping and are not counted.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GROUPS", "PAPER_MODULES", "parameter_groups", "table4"]

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
    "patch": "patch refinement (ours)",
    "layout": "coarse layout (ours)",
    "residual": "residual Gaussian (ours)",
    "ichm_iv": "core norm quantiles (ours)",
    "ichm_coupling": "core member ranks (ours)",
}


#: The subtotal row of the paper's own modules (the rows not marked "(ours)"): what a model
#: fitted and used as the paper's pipeline (``--paper``) needs; "total" also counts ours.
PAPER_MODULES = "the paper's modules"


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


def table4(dims, channels, n_colours, n_bins, sdr_shape, stored, n_classes=None) -> dict:
    """The rows of :meth:`tghop.TGHop.n_parameters`: each module's formula, the paper's
    count for these dimensions and the numbers stored.

    Parameters
    ----------
    dims : dict
        ``TGHop.dims_`` (D_r, N, F, W).
    channels : list of int
        Kept channels per hop (K1, K2, ...).
    n_colours : int
        Exemplar channels C.
    n_bins : int
        Bins per CDF.
    sdr_shape : tuple
        The core's (h, w, K).
    stored : dict
        :func:`parameter_groups` of the model's arrays.
    n_classes : int, optional
        Colour classes K; 0: none, the colour matching stores the C*257 quantiles only
        (None: the formula with K).
    """
    d, k, c_in, nb = dims, channels, n_colours, n_bins
    k1, d_r, n, f, w = k[0], d["D_r"], d["N"], d["F"], d["W"]
    block = sdr_shape[0] * sdr_shape[1]
    paper = {
        "transform stage 1": (f"{4 * c_in}*K1 + 1", 4 * c_in * k1 + 1),
        # Per c/w hop, the paper's 4 * K_parent * K_child + K_parent (two hops: 4 K1 K2 + K1; three: the formula
        # said 4*K1*K2 + K1 of a count that held hop 3's too, 0.58).
        "transform stage 2": (" + ".join(f"4*K{i}*K{i + 1} + K{i}" for i in range(1, len(k))),
                              sum(4 * a * b + a for a, b in zip(k[:-1], k[1:]))),
        "core SDR": (f"{block}*D_r", block * d_r),
        "core ICHM (i)": ("N", n),
        "core ICHM (ii)": ("F*D_r", f * d_r),
        "core ICHM (iii)": (f"3*F + {nb}*W", 3 * f + nb * w),
    }
    paper["colour matching (ours)"] = (
        ("C*257, no colour classes" if n_classes == 0 else
         f"C*257 + K*(C+2+C*257) + 2, K{'' if n_classes is None else f'={n_classes}'} colour classes")
        + " (not in the paper)", 0)
    paper["residual Gaussian (ours)"] = ("sum of K_c^2 over core channels (not in the paper)", 0)
    paper["core norm quantiles (ours)"] = ("2*N*33 (not in the paper)", 0)
    paper["core member ranks (ours)"] = ("members x components, summed over clusters (not in the paper)", 0)
    paper["coarse layout (ours)"] = ("a coarse TGHop model (not in the paper)", 0)
    paper["refinement (ours)"] = ("(levels*orientations+1)*C*257 + C*(C+1) + K*C*257 (not in the paper)", 0)
    paper["patch refinement (ours)"] = ("levels*16*32*(D+129), D = 49*C (not in the paper)", 0)
    rows = {m: {"formula": fm, "paper": int(p), "stored": int(stored.get(m, 0))} for m, (fm, p) in paper.items()}
    theirs = [v for m, v in rows.items() if not m.endswith("(ours)")]  # what the paper's pipeline (--paper) uses
    return {**rows,
            PAPER_MODULES: {"formula": "the rows not marked (ours)", "paper": sum(v["paper"] for v in theirs),
                            "stored": sum(v["stored"] for v in theirs)},
            "total": {"formula": "sum", "paper": sum(v["paper"] for v in rows.values()),
                      "stored": sum(v["stored"] for v in rows.values())}}
