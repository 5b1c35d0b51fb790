"""Bounds that the library checks and the command line checks too, before any work (no
imports: the command line reads them without loading NumPy, and each has one value)."""

__all__ = ["MAX_BOOST"]

#: Largest factor of :func:`tghop.cooc.assembly.boost_condition` (``tghop cooc edit --boost``,
#: the local page's edits): a bin's share p of a cell becomes p f / (p f + 1 - p), so 1000
#: takes a 1 % bin to 91 %; more changes next to nothing.
MAX_BOOST = 1000.0
