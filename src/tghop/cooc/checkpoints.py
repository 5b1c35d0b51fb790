"""The co-occurrence cGAN's checkpoint file (``.pt``): :func:`save` writes one, :func:`read` reads it.

A checkpoint is a ``torch.save`` dict of tensors only, so that it loads with
``weights_only=True``:

* ``generator.*``, ``critic.*`` and, with ``ema > 0``, ``generator_ema.*``: the networks'
  state dicts;
* ``opt_g.INDEX.NAME``, ``opt_d.INDEX.NAME``: the two Adam optimisers' per-parameter state;
* ``centres_``, ``spreads_``, ``cond_mean_``, ``cond_std_``, ``exemplar_cooc_``,
  ``history_``: the model's statistics (float64);
* ``torch_rng``: the state of training's random numbers;
* ``settings_json``: UTF-8 JSON bytes with ``kind`` (:data:`KIND`), ``format``
  (:data:`FORMAT`), the checked ``settings``, ``step``, ``seed``, ``exemplar_shape``,
  ``exemplar_hash``, the optimisers' ``optimiser_groups`` and ``device``.

This module does not import the model: :meth:`tghop.cooc.model.CoocGAN.save` calls
:func:`save`, and :func:`tghop.cooc.model.load` calls :func:`read` with the class to build.
"""

from __future__ import annotations

import io
import json
import numbers
from pathlib import Path

import numpy as np

from .._errors import ModelFileError, TGHopError
from .._json import RepeatedKeyError, loads_unique
from .._archives import check_archive_bounds
from .._resources import import_torch
from .config import MAX_STEPS, torch_device
from .networks import build_networks

__all__ = ["KIND", "FORMAT", "save", "read"]

#: ``kind`` field of a checkpoint's settings; a ``.pt`` without it is not ours.
KIND = "tghop.cooc"
#: Checkpoint format version.
FORMAT = 1

#: The model's statistics, stored as float64 tensors under their own names.
_STATISTICS = ("centres_", "spreads_", "cond_mean_", "cond_std_", "exemplar_cooc_", "history_")


def _networks_of(model):
    """``(prefix, module)`` of the networks a checkpoint stores (the average with ``ema > 0``)."""
    modules = [("generator", model.generator_), ("critic", model.critic_)]
    if hasattr(model, "generator_ema_"):
        modules.append(("generator_ema", model.generator_ema_))
    return modules


def save(model, path) -> None:
    """Write a trained :class:`~tghop.cooc.model.CoocGAN` to ``path`` (atomically).

    See the module's docstring for what is stored.

    Parameters
    ----------
    model : tghop.cooc.model.CoocGAN
        Fitted (or loaded): its networks, optimiser states, statistics, settings and the
        random-number state of its training.
    path : str or path-like
        The ``.pt`` file to write; a half-written file is never left there.

    Raises
    ------
    NotFittedError
        Before ``fit``.
    ModelFileError
        When ``path`` cannot be written (a folder, a missing parent, ...).
    """
    model._check_fitted()
    torch = import_torch("the co-occurrence cGAN")
    from ..imageio import check_output_path, write_atomic

    check_output_path(path, what="checkpoint", error=ModelFileError)
    tensors = {}
    for prefix, module in _networks_of(model):
        for name, value in module.state_dict().items():
            tensors[f"{prefix}.{name}"] = value.detach().cpu()
    groups = {}
    for prefix, opt in (("opt_g", model._opt_g), ("opt_d", model._opt_d)):
        sd = opt.state_dict()
        groups[prefix] = sd["param_groups"]
        for index, state in sd["state"].items():
            for name, value in state.items():
                tensors[f"{prefix}.{index}.{name}"] = torch.as_tensor(value).detach().cpu()
    for name in _STATISTICS:
        tensors[name] = torch.as_tensor(np.asarray(getattr(model, name), dtype=np.float64))
    tensors["torch_rng"] = model._torch_gen.get_state().cpu()
    settings = {"kind": KIND, "format": FORMAT, "settings": model.settings_, "step": int(model.step_),
                "seed": int(model._seed_), "exemplar_shape": list(model.exemplar_shape_),
                "exemplar_hash": model.exemplar_hash_, "optimiser_groups": groups,
                "device": model.device if isinstance(model.device, str) else "auto"}
    tensors["settings_json"] = torch.frombuffer(bytearray(json.dumps(settings).encode()), dtype=torch.uint8)

    def write(f):
        buffer = io.BytesIO()
        torch.save(tensors, buffer)
        f.write(buffer.getvalue())

    write_atomic(path, write)


def read(path, model_class, *, device: str = "auto"):
    """A model of ``model_class`` (:class:`~tghop.cooc.model.CoocGAN`) from the checkpoint at ``path``.

    Parameters
    ----------
    path : str or os.PathLike
    model_class : type
        The class to build (passed in: this module does not import the model, which
        imports it).
    device : str
        Where to put the networks (``"auto"``: CUDA when present).

    Returns
    -------
    model_class
        Trained, in evaluation mode; ``fit(exemplar, resume=True)`` continues it.

    Raises
    ------
    ModelFileError
        Missing file, not a tghop co-occurrence checkpoint, or another format version; or an archive
        that would unpack to far more than its size (a decompression bomb; 0.57), refused unread.
    TGHopError
        An unknown ``device``, or CUDA where there is none.
    """
    if not str(path).strip():  # Path("") is the current folder: ".: no such checkpoint"
        raise ModelFileError("the checkpoint's file name is empty; give one")
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such checkpoint; check the path, or train one (CoocGAN().fit(exemplar)"
                             f".save(path), or 'tghop cooc train EXEMPLAR -o {path.name}')")
    torch = import_torch("the co-occurrence cGAN")
    torch_device(torch, device)  # a bad device named as such, not as a corrupt file
    check_archive_bounds(path, path, "a checkpoint", "give a checkpoint 'tghop cooc train' wrote, or train it again")
    try:
        tensors = torch.load(path, map_location="cpu", weights_only=True)
        settings = loads_unique(bytes(tensors["settings_json"].numpy().tobytes()).decode())
    except RepeatedKeyError as exc:  # 0.59 kept the last value without a word
        raise ModelFileError(f"{path}: corrupt checkpoint settings (the key {exc.key[:60]!r} is given twice); train "
                             "it again") from None
    except Exception:
        raise ModelFileError(f"{path}: not a tghop co-occurrence checkpoint (one is written by CoocGAN.save or "
                             "'tghop cooc train')") from None
    if not isinstance(settings, dict) or settings.get("kind") != KIND:
        raise ModelFileError(f"{path}: a checkpoint of another kind "
                             f"({settings.get('kind') if isinstance(settings, dict) else '?'!r}), "
                             "not a tghop co-occurrence model; train one (CoocGAN().fit(exemplar).save(path), "
                             "or 'tghop cooc train')")
    if settings.get("format") != FORMAT:
        raise ModelFileError(f"{path}: checkpoint format {settings.get('format')} but this tghop reads "
                             f"format {FORMAT}; train it again with this version")
    try:
        p = {"tiles": 1, "ema": 0.0, "kernel": 5, "padding": "zeros", "gp_every": 1, "lr_decay": 0.0,
             "context": False, **settings["settings"]}  # checkpoints from before these settings
        _check_sizes(p, settings["exemplar_shape"], tensors)  # before 2**n_layers is computed or a network built
        model = model_class(**p, device=device)
        model.settings_ = model._settings()
        model.exemplar_shape_ = tuple(settings["exemplar_shape"])
        model.exemplar_hash_ = settings["exemplar_hash"]
        model._seed_ = int(settings["seed"])
        model.rng = model._seed_
        model.step_ = int(settings["step"])
        for name in _STATISTICS:
            setattr(model, name, tensors[name].numpy())
        _check_state(path, model, torch, tensors)
        model._to_device(torch)
        model.generator_, model.critic_ = build_networks(torch, model.exemplar_shape_[2], len(model.cond_mean_),
                                                         model.settings_)
        model._make_averaged()
        for prefix, module in _networks_of(model):
            module.load_state_dict({k[len(prefix) + 1 :]: v for k, v in tensors.items() if k.startswith(prefix + ".")})
            module.to(model._device).eval()
        model._memory_format(torch, train=False)
        model._make_optimisers(torch)
        for prefix, opt in (("opt_g", model._opt_g), ("opt_d", model._opt_d)):
            state: dict = {}
            for key, value in tensors.items():
                if key.startswith(prefix + "."):
                    _, index, name = key.split(".", 2)
                    state.setdefault(int(index), {})[name] = value
            opt.load_state_dict({"state": state, "param_groups": settings["optimiser_groups"][prefix]})
        model._torch_gen = torch.Generator(device=model._device)
        model._torch_gen.set_state(tensors["torch_rng"])
    except ModelFileError:
        raise
    except Exception as exc:
        raise ModelFileError(f"{path}: corrupt tghop co-occurrence checkpoint ({_what_is_wrong(exc)}); "
                             "train it again") from None
    return model


def _whole(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def _check_sizes(p, shape, tensors) -> None:
    """A one-line :class:`TGHopError` naming the integer setting of a checkpoint's settings ``p`` that its
    own contents rule out (0.58; 0.57 refused any over 2**16, a guess, and took n_clusters=60,000 for an
    exemplar of 4,096 pixels). From what each means, for the exemplar ``shape`` (H, W, C) and the stored
    ``tensors``: ``n_clusters`` k-means colours of its pixels, at most H*W and at least the centres stored;
    ``crop_size`` x ``tiles`` the training crops cut from it, at most its smaller side; ``n_layers`` cells of
    2**n_layers pixels within a crop; ``patch`` and ``window`` squares on it, at most 2*max(H, W) + 1 (one
    that wide covers the whole exemplar from every pixel); ``noise_channels``, ``kernel`` and the widths what
    the generator's and critic's stored convolutions hold; ``batch_size``, ``n_critic`` and ``gp_every``
    (training's alone) at most :data:`~tghop.cooc.config.MAX_STEPS`, the most steps a training runs.
    Values of the wrong type, and an exemplar shape or tensors that are not there, are left to
    :func:`~tghop.cooc.config.check_settings` and :func:`_check_state`."""
    if not (isinstance(shape, (list, tuple)) and len(shape) == 3 and all(_whole(v) and v > 0 for v in shape)):
        return
    h, w, _ = shape
    ints = {name: p.get(name) for name in ("n_clusters", "crop_size", "tiles", "n_layers", "patch", "window",
                                           "noise_channels", "kernel", "batch_size", "n_critic", "gp_every")}
    if not all(_whole(v) and v > 0 for v in ints.values()):
        return
    crop, tiles, layers = ints["crop_size"], ints["tiles"], ints["n_layers"]

    def refuse(name, why):
        raise TGHopError(f"{name}={ints[name]:,} {why}")

    centres = tensors.get("centres_")
    k = int(centres.shape[0]) if centres is not None and centres.ndim == 2 else 0
    if ints["n_clusters"] > h * w:
        refuse("n_clusters", f"colours, more than the exemplar's {h}x{w} pixels")
    if ints["n_clusters"] < k:
        refuse("n_clusters", f"but {k} colour centres are stored")
    if crop * tiles > min(h, w):
        raise TGHopError(f"crop_size={crop:,} x tiles={tiles:,}: training crops of {crop * tiles:,} pixels, larger "
                         f"than the {h}x{w} exemplar they are cut from")
    if layers > crop.bit_length() - 1:
        refuse("n_layers", f"makes cells of 2**{layers:,} pixels, larger than crop_size={crop:,}")
    for name in ("patch", "window"):
        if ints[name] > 2 * max(h, w) + 1:
            refuse(name, f"pixels across, more than twice the {h}x{w} exemplar")
    for name, meaning in (("batch_size", "crops a step"), ("n_critic", "critic steps a generator step"),
                          ("gp_every", "critic steps between gradient penalties")):
        if ints[name] > MAX_STEPS:
            refuse(name, f"{meaning}, more than the {MAX_STEPS:,} steps a training runs at most")
    first, cond = tensors.get("generator.net.1.weight"), tensors.get("cond_mean_")
    if first is not None and first.ndim == 4 and k and cond is not None and cond.shape == (k * k,):  # else _check_state
        if ints["kernel"] != first.shape[-1]:
            refuse("kernel", f"but the generator's convolutions are {first.shape[-2]}x{first.shape[-1]}")
        if ints["noise_channels"] != first.shape[1] - k * k:
            refuse("noise_channels", f"but the generator's first convolution takes {first.shape[1] - k * k} "
                                     f"noise channels besides the {k * k} of the condition")
    for name, key in (("g_widths", "generator.net.{}.weight"), ("d_widths", "critic.convs.{}.weight")):
        widths = p.get(name)
        if not isinstance(widths, (list, tuple)) or not all(_whole(v) for v in widths):
            continue
        for i, width in enumerate(widths):
            tensor = key.format(4 * i + 1 if name == "g_widths" else i)
            stored = tensors.get(tensor)
            if stored is not None and stored.ndim == 4 and width != stored.shape[0]:
                raise TGHopError(f"{name}={list(widths)} but {tensor} has {stored.shape[0]} output channels, "
                                 f"not {width}")


def _what_is_wrong(exc) -> str:
    """A corrupt checkpoint's fault in words, where the exception says it: a missing key by name,
    a setting's own message, the first of PyTorch's load_state_dict lines (a tensor of the wrong
    shape by name); else the exception's class (0.56 gave the class alone: "(KeyError)")."""
    if isinstance(exc, KeyError) and exc.args:
        return f"{exc.args[0]!r} is missing"
    if isinstance(exc, TGHopError):
        return str(exc)
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    if isinstance(exc, RuntimeError) and len(lines) > 1 and "state_dict" in lines[0]:
        return lines[1][:160]
    return exc.__class__.__name__


def _check_state(path, model, torch, tensors) -> None:
    """A one-line :class:`ModelFileError` where the checkpoint's statistics, exemplar shape or
    generator weights disagree with its settings or are not finite (a changed or damaged file
    generated nonsense, or failed at generation with an error naming no file)."""
    p = model.settings_

    def corrupt(what):
        raise ModelFileError(f"{path}: corrupt tghop co-occurrence checkpoint ({what}); train it again")

    shape = model.exemplar_shape_
    if (len(shape) != 3 or not all(isinstance(v, int) and not isinstance(v, bool) for v in shape)
            or min(shape[:2]) < p["crop_size"] * p["tiles"] or shape[2] < 1):
        corrupt(f"exemplar shape {list(shape)} for training crops of {p['crop_size'] * p['tiles']} pixels")
    k = model.centres_.shape[0] if model.centres_.ndim == 2 else 0
    expected = {"centres_": (k, shape[2]), "spreads_": (k, shape[2]), "cond_mean_": (k * k,),
                "cond_std_": (k * k,), "exemplar_cooc_": (k * k, shape[0] // model.s, shape[1] // model.s)}
    if not 1 <= k <= p["n_clusters"]:
        corrupt(f"centres_ of shape {model.centres_.shape} for n_clusters {p['n_clusters']}")
    for name, want in expected.items():
        value = getattr(model, name)
        if value.shape != want:
            corrupt(f"{name} has shape {value.shape}, not {want}")
        if not np.isfinite(value).all():
            corrupt(f"{name} has NaN or infinite values")
    for name in ("spreads_", "cond_std_"):
        if not (getattr(model, name) > 0).all():
            corrupt(f"{name} has values not above 0")
    if (model.exemplar_cooc_ < 0).any():
        corrupt("exemplar_cooc_ has negative values")
    if model.history_.ndim != 2 or model.history_.shape[1] != 5:
        corrupt(f"history_ has shape {model.history_.shape}, not (steps, 5)")
    for name in _STATISTICS:  # 0.56 took complex or integer ones
        if getattr(model, name).dtype.kind != "f":
            corrupt(f"{name} is of type {getattr(model, name).dtype}, not real floating point")
    for key, value in tensors.items():
        counter = key.endswith(".num_batches_tracked")  # batch norm's count: an integer
        if key.startswith(("generator.", "generator_ema.", "critic.", "opt_g.", "opt_d.")) and not counter \
                and not value.is_floating_point():  # 0.56 generated from complex weights
            corrupt(f"{key} is of type {str(value.dtype).replace('torch.', '')}, not real floating point")
        if key.startswith(("generator.", "generator_ema.")) and value.is_floating_point() \
                and not bool(torch.isfinite(value).all()):
            corrupt(f"{key} has NaN or infinite values")
