"""The two configurations of the co-occurrence cGAN and the check of its settings.

:data:`SMALL` (the default: made for a 2-core CPU) and :data:`PAPER` (the paper's setting,
for a GPU) list every training setting of :class:`tghop.cooc.model.CoocGAN` with its
value; :func:`check_settings` turns a model's settings into plain, checked JSON values
(what :meth:`~tghop.cooc.model.CoocGAN.fit` trains with and a checkpoint stores).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .._errors import TGHopError

__all__ = ["SMALL", "PAPER", "MAX_STEPS", "check_settings", "torch_device"]

#: The small configuration, the default of :class:`~tghop.cooc.model.CoocGAN`: made to
#: train on a 2-core CPU for a 256 x 256 exemplar. Everything spatial is at half the paper's
#: scale (64 px crops, 33 px patches, 25 px windows, sigma^2 = 13), the networks have 4
#: layers instead of 5 (so s = 16 keeps a 4 x 4 condition) and 8 to 16 times fewer
#: filters, one critic step per generator step (as the authors' released code, ``dIter=1``).
#: Not in the paper (issue 9, docs/choices.md): 5,500 generator steps of 8 crops with a
#: lazy gradient penalty (``gp_every=4``), which in a GPU sweep at equal CPU time beat
#: 3,000 steps of 16 crops on brick_wall, grass_lawn and red_peppers (3 seeds each);
#: and it generates with an exponential moving average of
#: the generator's weights, ``ema=0.995`` (a half-life of 138 steps; better than the raw
#: generator on the brick_wall seeds measured, longer averages worse).
SMALL = dict(
    n_clusters=8, crop_size=64, n_layers=4, patch=33, window=25, sigma=math.sqrt(13.0),
    g_widths=(64, 32, 16), d_widths=(16, 32, 64), noise_channels=16,
    n_crops=1000, batch_size=8, n_steps=5500, n_critic=1,
    lr=2e-4, beta1=0.5, beta2=0.999, lambda_gp=1.0, lambda_cooc=10.0, tiles=1, ema=0.995,
    kernel=5, padding="zeros", gp_every=4, lr_decay=0.0, context=False,
)

#: The paper's configuration (Sec. 4.1): k = 8, 2,000 crops of 128 x 128, s = 32 (5 layers,
#: a 4 x 4 condition), 65 px patches, 51 px windows, sigma^2 = 51, 120 epochs, Adam
#: (lr 2e-4, beta1 0.5), gradient penalty weight 1. From PSGAN (Bergmann et al. 2017,
#: the paper's base): 5 x 5 filters, widths 512-256-128-64 (generator) and 64-128-256-512
#: (critic), batch 64, Adam beta2 = 0.999, N(0, 0.02) initialisation, tanh output, leaky
#: ReLU 0.2 in the critic; 30 noise channels (PSGAN's released model uses 30 local noise
#: dimensions). From WGAN-GP (Gulrajani et al.): 5 critic steps per generator step, no
#: batch norm in the critic. Not in any of them: the consistency weight 10.
#: One epoch is n_crops / batch_size generator steps: 120 epochs = 3,750 steps (minutes on
#: a GPU; docs/choices.md has the times). The authors' released code
#: (github.com/Ashu7397/cooc_texture) differs from these borrowed values: batch 16, one
#: critic step, widths 960-480-240-120 / 120-240-480-960, 64 noise channels, so 120 epochs
#: are 15,000 steps there; see docs/choices.md.
PAPER = dict(
    n_clusters=8, crop_size=128, n_layers=5, patch=65, window=51, sigma=math.sqrt(51.0),
    g_widths=(512, 256, 128, 64), d_widths=(64, 128, 256, 512), noise_channels=30,
    n_crops=2000, batch_size=64, n_steps=3750, n_critic=5,
    lr=2e-4, beta1=0.5, beta2=0.999, lambda_gp=1.0, lambda_cooc=10.0, tiles=1, ema=0.0,
    kernel=5, padding="zeros", gp_every=1, lr_decay=0.0, context=False,
)

#: Most generator steps (``n_steps``) a training runs: ten times the 15,000 of the authors'
#: released code (120 epochs there; about 7 hours of the small configuration on a 2-core
#: CPU). A larger count is refused instead of training for days.
MAX_STEPS = 150_000

def _whole(name, value) -> int:
    """``value`` as an int (a Python or NumPy integer); a bool, a float (64.0 too, as TGHop's
    settings: :class:`tghop.settings.Setting`) or a string is refused with the setting's ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        whole = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)) and math.isfinite(
            value) and float(value).is_integer()
        raise TGHopError(f"{name} must be an integer, got {value!r}" + (f"; write {int(value)}" if whole else ""))
    return int(value)


def _number(name, value) -> float:
    """``value`` as a float; a bool or a string is refused with the setting's ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TGHopError(f"{name} must be a number, got {value!r}")
    return float(value)


def check_settings(values) -> dict:
    """The training settings in ``values`` (a mapping with every key of :data:`SMALL`) as
    plain JSON values, checked: a one-line :class:`TGHopError` for a bad one.

    Integer settings take integers (or floats without a fraction, 64.0), never a bool or
    a fraction; the widths are sequences of them; ``context`` is a bool (or 0 or 1).

    Parameters
    ----------
    values : mapping
        Setting name -> value, with every key of :data:`SMALL` (other keys, such as
        ``device`` and ``rng``, are ignored).

    Returns
    -------
    dict
        The keys of :data:`SMALL`, ints, floats, lists of int, a str and a bool.
    """
    p = {name: values[name] for name in SMALL}
    ints = ("n_clusters", "crop_size", "n_layers", "patch", "window", "noise_channels", "n_crops",
            "batch_size", "n_steps", "n_critic", "tiles", "kernel", "gp_every")
    for name in ints:
        p[name] = _whole(name, p[name])
    for name in ("sigma", "lr", "beta1", "beta2", "lambda_gp", "lambda_cooc", "ema", "lr_decay"):
        p[name] = _number(name, p[name])
    for name in ("g_widths", "d_widths"):
        try:
            if isinstance(p[name], (str, bytes)):
                raise TypeError
            widths = list(p[name])
        except TypeError:
            raise TGHopError(f"{name} must be a sequence of integers, got {p[name]!r}") from None
        p[name] = [_whole(f"{name} entry", v) for v in widths]
        if any(v < 1 for v in p[name]):
            raise TGHopError(f"{name} entries must be positive integers, got {p[name]}")
    for name in ints:
        if p[name] < (0 if name == "n_steps" else 1):
            raise TGHopError(f"{name} must be {'0 or more' if name == 'n_steps' else 'positive'}, got {p[name]}")
    if p["n_steps"] > MAX_STEPS:
        raise TGHopError(f"n_steps must be at most {MAX_STEPS:,}, got {p['n_steps']:,}")
    if p["n_layers"] < 2:
        raise TGHopError(f"n_layers must be at least 2, got {p['n_layers']}")
    if p["crop_size"] % (2 ** p["n_layers"]):
        raise TGHopError(f"crop_size ({p['crop_size']}) must be a multiple of 2**n_layers = {2 ** p['n_layers']}")
    if not (p["sigma"] > 0 and p["lr"] > 0 and 0 <= p["beta1"] < 1 and 0 <= p["beta2"] < 1
            and p["lambda_gp"] >= 0 and p["lambda_cooc"] >= 0 and 0 <= p["ema"] < 1):
        raise TGHopError("sigma and lr must be positive, betas and ema in [0, 1), the loss weights >= 0")
    if p["kernel"] % 2 == 0:
        raise TGHopError(f"kernel must be odd, got {p['kernel']}")
    if p["padding"] not in ("zeros", "reflect", "replicate"):
        raise TGHopError(f"padding must be 'zeros', 'reflect' or 'replicate', got {p['padding']!r}")
    if not isinstance(p["context"], (bool, np.bool_)) and not (
            isinstance(p["context"], numbers.Integral) and p["context"] in (0, 1)):
        raise TGHopError(f"context must be True or False, got {p['context']!r}")
    p["context"] = bool(p["context"])
    if not 0 <= p["lr_decay"] <= 1:
        raise TGHopError(f"lr_decay must be in [0, 1], got {p['lr_decay']}")
    return p


def torch_device(torch, device):
    """The torch device named by ``device`` (``"auto"`` or None: CUDA when present), or a
    one-line :class:`TGHopError` naming the device (an unknown name, or CUDA where there is none).

    Parameters
    ----------
    torch : module
        The imported ``torch`` (passed in: this module does not import PyTorch).
    device : str, torch.device or None
        ``"auto"`` or None, ``"cpu"``, ``"cuda"``, ``"cuda:1"``, ...

    Returns
    -------
    torch.device
    """
    if device in (None, "auto"):
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError):
        raise TGHopError(f"device must be 'auto', 'cpu', 'cuda' or a torch device name, got {device!r}") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise TGHopError(f"device {device!r} but CUDA is not available here; use device='cpu' or 'auto'")
    return dev
