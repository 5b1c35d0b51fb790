"""JSON read with every object's keys once (:func:`loads_unique`): :func:`json.loads` keeps a repeated
key's last value without a word, so a manifest row ``{"size": "512x512", ..., "size": "64x64"}`` or a
model file's metadata edited by hand said one thing and did another (0.58). Standard library only."""

import json

__all__ = ["RepeatedKeyError", "loads_unique"]


class RepeatedKeyError(ValueError):
    """A JSON object gives ``key`` more than once (a :class:`ValueError`, as :func:`json.loads`' errors are)."""

    def __init__(self, key):
        super().__init__(f"the key {key!r} is given twice")
        self.key = key


def _unique(pairs):
    """``object_pairs_hook``: the object as a dict, or :class:`RepeatedKeyError` for its first repeated key."""
    out = {}
    for key, value in pairs:
        if key in out:
            raise RepeatedKeyError(key)
        out[key] = value
    return out


def loads_unique(text):
    """:func:`json.loads` of ``text`` (str or bytes), refusing an object (at any depth) that repeats a key.

    Raises
    ------
    RepeatedKeyError
        The first repeated key (its ``key``).
    ValueError, RecursionError
        As :func:`json.loads`.
    """
    return json.loads(text, object_pairs_hook=_unique)
