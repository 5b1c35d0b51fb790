"""One setting of TGHop (:class:`Setting`): its name, default, kind and allowed range, its help text
and command-line option; how a value of it is checked (:meth:`Setting.check`, one-line
:class:`~tghop.TGHopError`), read from the command line (:meth:`Setting.parse`) and written in a
docstring (:meth:`Setting.doc_type`); and the one check of a hop's channel rule
(:func:`check_channel_rule`).

The table of every setting, and what is made from it, is :mod:`tghop.settings` (which re-exports
these names). Nothing here imports NumPy, scikit-learn or SciPy: the command line reads the table
before it loads them.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Any, Optional, Tuple

from ._errors import TGHopError

__all__ = ["Setting", "check_channel_rule"]

_MISSING = object()


def _number(value) -> str:
    """A bound as people write it: 10,000,000 rather than 1e+07; 0.5 stays 0.5."""
    if float(value).is_integer() and abs(value) >= 1000:
        return f"{int(value):,}"
    return f"{value:g}"


@dataclass(frozen=True)
class Setting:
    """One setting of TGHop.

    Parameters
    ----------
    name : str
        Python name: a ``TGHop`` constructor parameter (fit) or ``synthesize`` keyword
        (generate).
    default : object
    kind : {"int", "float", "bool", "choice", "channels", "rng"}
    help : str
        One or two sentences; used for the docstring and ``--help``.
    when : {"fit", "generate"}
        "fit": part of the model (constructor parameter, stored in model files, needs a
        refit to change). "generate": a ``synthesize`` keyword, given per call.
    low, high : float, optional
        Allowed range (inclusive unless ``low_open`` / ``high_open``).
    low_open, high_open : bool
        The bound itself is not allowed.
    none_ok : bool
        None is allowed (meaning "off" or "automatic", see the help).
    auto : bool
        None means "automatic": the command line's word for it is ``auto`` (else ``none``
        or ``off``).
    choices : tuple
        Allowed values of a "choice" setting.
    cli : tuple of str or None
        Command-line option names; ``()`` gives ``--name-with-dashes``; None keeps the
        setting off the command line (or handled specially there, as ``n_channels``).
    cli_high : float, optional
        A tighter upper bound on the command line only.
    paper : object, optional
        Value under ``--paper`` (the paper's Table 4 setting) where it differs from or
        pins the default.
    target : str, optional
        ``"ichm"`` or ``"sdr"`` (same parameter name) or ``"ichm.max_iter"``: the
        fitted component that receives this setting.
    """

    name: str
    default: Any
    kind: str
    help: str
    when: str = "fit"
    low: Optional[float] = None
    high: Optional[float] = None
    low_open: bool = False
    high_open: bool = False
    none_ok: bool = False
    auto: bool = False
    choices: Tuple = ()
    cli: Optional[Tuple[str, ...]] = ()
    cli_high: Optional[float] = None
    paper: Any = field(default=_MISSING)
    target: Optional[str] = None

    # ------------------------------------------------------------ checking
    @property
    def has_paper(self) -> bool:
        return self.paper is not _MISSING

    def range_text(self, *, cli: bool = False, json: bool = False) -> str:
        """The values the setting takes, in words; ``cli``: None as the command line writes it,
        ``json``: as JSON does (``null``).

        Parameters
        ----------
        cli : bool
            Name None ``auto`` or ``none``, as the command line takes it.
        json : bool
            Name None ``null`` (when not ``cli``).

        Returns
        -------
        str
            E.g. ``"an integer >= 1 or None"``, ``"one of 'a', 'b'"``.
        """
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        parts = []
        if self.low is not None:
            parts.append(f"{'>' if self.low_open else '>='} {_number(self.low)}")
        if self.high is not None:
            parts.append(f"{'<' if self.high_open else '<='} {_number(self.high)}")
        noun = {"int": "an integer", "float": "a finite number", "bool": "True or False"}.get(self.kind, "")
        text = noun + (" " + " and ".join(parts) if parts else "")
        none = ("auto" if self.auto else "none") if cli else "null" if json else "None"
        return text + (f" or {none}" if self.none_ok else "")

    def check(self, value, *, label=None, cli=False, json=False):
        """Return ``value`` (normalised) or raise a one-line :class:`TGHopError`; an ``"int"``
        setting takes integers only (Python or NumPy, not a float such as 2.0); ``cli``: the
        message names None as the command line writes it (``auto`` or ``none``), ``json`` as
        JSON does (``null``).

        Parameters
        ----------
        value : object
            The value given.
        label : str, optional
            The name in the message (default the setting's name).
        cli, json : bool
            How the message writes None (:meth:`range_text`).

        Returns
        -------
        object
            ``value`` normalised: an ``int`` or ``float`` for numbers, ``bool``, a tuple of
            rules for ``"channels"``, None where allowed; an ``"rng"`` setting's value as given.
        """
        label = label or self.name
        words = self.range_text(cli=cli, json=json)
        if self.kind == "rng":
            return value  # checked where it is used (check_rng)
        if value is None:
            if self.none_ok:
                return None
            raise TGHopError(f"{label} must be {words}, got {'null' if json else None}")
        if self.kind == "channels":
            return _check_channels(value, label)
        if self.kind == "choice":
            if value not in self.choices:
                raise TGHopError(f"{label} must be {words}, got {value!r}")
            return value
        if self.kind == "bool":
            if type(value).__name__ not in ("bool", "bool_") and not (
                    isinstance(value, numbers.Integral) and value in (0, 1)):
                raise TGHopError(f"{label} must be True or False, got {value!r}")
            return bool(value)
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise TGHopError(f"{label} must be {words}, got {value!r}")
        if self.kind == "int":
            if not isinstance(value, numbers.Integral):  # 2.0 too, as the server and the other entry points
                whole = math.isfinite(value) and float(value).is_integer()
                raise TGHopError(f"{label} must be {words}, got {value!r}"
                                 + (f"; write {int(value)}" if whole else ""))
            value = int(value)
        else:
            value = float(value)
            if not math.isfinite(value):
                raise TGHopError(f"{label} must be {words}, got {value!r}")
        bad_low = self.low is not None and (value <= self.low if self.low_open else value < self.low)
        bad_high = self.high is not None and (value >= self.high if self.high_open else value > self.high)
        if bad_low or bad_high:
            raise TGHopError(f"{label} must be {words}, got {value!r}")
        return value

    def parse(self, text: str):
        """A command-line string -> value (then :meth:`check`); raises TGHopError, whose line names
        the word for None where the setting takes it (``'abc' is not an integer (or auto)``).

        Parameters
        ----------
        text : str
            An option's value (spaces around ignored); ``auto`` (or ``none``, ``off``) is
            None where the setting takes None.

        Returns
        -------
        int, float, object or None
            The value, not yet checked against the range (:meth:`check`); a ``"choice"``
            setting's choice whose text is ``text``.
        """
        text = str(text).strip()
        if self.none_ok and text.lower() in (("auto",) if self.auto else ("none", "off")):
            return None
        word = f" (or {'auto' if self.auto else 'none'})" if self.none_ok else ""
        if self.kind == "int":
            try:
                return int(text)
            except ValueError:
                raise TGHopError(f"{text!r} is not an integer{word}") from None
        if self.kind == "float":
            try:
                return float(text)
            except ValueError:
                raise TGHopError(f"{text!r} is not a number{word}") from None
        if self.kind == "choice":
            for c in self.choices:
                if str(c) == text:
                    return c
            raise TGHopError(f"{text!r} is not {self.range_text()}")
        raise TGHopError(f"{self.name} cannot be parsed from text")

    # ------------------------------------------------------------ presentation
    @property
    def option_names(self) -> Tuple[str, ...]:
        if self.cli is None:
            return ()
        return self.cli or ("--" + self.name.replace("_", "-"),)

    def doc_type(self) -> str:
        """The setting's type line in numpydoc form.

        Returns
        -------
        str
            E.g. ``"int, default=32"``, ``"float or None, default=None"``; the ``rng``
            setting's without a default.
        """
        kinds = {"int": "int", "float": "float", "bool": "bool", "channels": "sequence or None",
                 "rng": "int or numpy.random.Generator, optional",
                 "choice": "{" + ", ".join(repr(c) for c in self.choices) + "}"}
        text = kinds[self.kind]
        if self.kind == "rng":
            return text
        if self.none_ok and self.kind != "channels":
            text += " or None"
        return f"{text}, default={self.default!r}"


def check_channel_rule(rule, name: str = "channel count", *, none_ok: bool = False):
    """One hop's channel rule: an int count >= 1, a fraction in (0, 1], or "knee".

    The one check of a channel rule (the settings table, :mod:`tghop.saab` and the
    command line's ``--k1``/``--k2``/``--k3`` call it). ``none_ok``: None ("keep every
    non-empty channel") is allowed too.

    Parameters
    ----------
    rule : int, float, str or None
        The rule given.
    name : str
        What the message calls it (``"n_channels: K1"``).
    none_ok : bool
        Allow None.

    Returns
    -------
    int, float, str or None
        ``rule`` as an ``int`` count, a ``float`` fraction, ``"knee"`` or None.

    Raises
    ------
    TGHopError
        One line naming ``name`` and the rules allowed.
    """
    if rule is None and none_ok:
        return None
    if isinstance(rule, str) and rule == "knee":
        return rule
    if isinstance(rule, numbers.Integral) and not isinstance(rule, bool):
        if rule < 1:
            raise TGHopError(f"{name} must be at least 1 (or a fraction in (0, 1], or 'knee'), got {rule}")
        return int(rule)
    if isinstance(rule, numbers.Real) and not isinstance(rule, bool) and 0.0 < rule <= 1.0:
        return float(rule)
    raise TGHopError(f"{name} must be an integer >= 1, a fraction in (0, 1] or 'knee', got {rule!r}")


def _check_channels(value, label):
    """A sequence of per-hop rules (:func:`check_channel_rule`)."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise TGHopError(f"{label} must be a sequence of per-hop rules, e.g. (9, 22), got {value!r}")
    rules = tuple(value)
    if not rules:
        raise TGHopError(f"{label} must name at least one hop, got {value!r}")
    return tuple(check_channel_rule(rule, f"{label}: K{i}") for i, rule in enumerate(rules, start=1))
