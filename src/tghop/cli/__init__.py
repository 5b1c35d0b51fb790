"""The ``tghop`` command line.

:mod:`~tghop.cli.group` holds the command group (``main``) and how every command fails;
one module per family of commands stands below it (:mod:`~tghop.cli.texture`: fit,
synth, patches, clusters, info; :mod:`~tghop.cli.guided`: synth with several SOURCEs, morph;
:mod:`~tghop.cli.inpaint`: inpaint, extend; :mod:`~tghop.cli.evaluation`: evaluate,
baseline; :mod:`~tghop.cli.cooc`: the co-occurrence cGAN; :mod:`~tghop.cli.batch`: batch;
:mod:`~tghop.cli.serve`: serve), and below them the shared helpers
(:mod:`~tghop.cli.options`, :mod:`~tghop.cli.common`, which re-exports those of
:mod:`~tghop.cli.errors`: how a command fails and stops; :mod:`~tghop.cli.progress`: progress bars and log
lines; :mod:`~tghop.cli.inputs`: exemplars, images and masks read; :mod:`~tghop.cli.outputs`: outputs
checked and ``--stages``' files; :mod:`~tghop.cli.materials`: a material's maps named and written;
:mod:`~tghop.cli.lines`: the other lines a command prints, as a terminal shows them;
:mod:`~tghop.cli.help_sections`: the ``--help`` of the commands with many options). The ``tghop`` command
itself starts in :func:`tghop.__main__.run`.
"""

from .group import main

__all__ = ["main"]
