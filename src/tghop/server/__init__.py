"""tghop's local web server (``tghop serve``): a page to fit, generate and download
textures, and the HTTP API under ``/api`` that the page uses (docs/serve.md).

* :mod:`tghop.server.app`: the Starlette application (:func:`~tghop.server.app.create_app`)
  and its table of routes;
* :mod:`tghop.server.routes`: the routes' handlers, a module per kind (fit and jobs, a
  model's file, images, inpaint and extend, co-occurrence checkpoints);
* :mod:`tghop.server.core`: the state the handlers share (:class:`~tghop.server.core.Server`:
  the cache, the fit queue, the bound on generations and their threads);
* :mod:`tghop.server.uploads`: a request read (its body within a limit, a form, JSON, an
  uploaded image decoded);
* :mod:`tghop.server.cache`: the cache folders (files named by content hashes, written
  atomically, bounded, the last used kept in memory);
* :mod:`tghop.server.cooc`: co-occurrence checkpoints (:mod:`tghop.cooc`): upload, morph and
  edit with crops of the exemplar (PyTorch imported only there; 501 without it);
* :mod:`tghop.server.requests`: the fields checked: a fit's form, the generation routes' JSON
  (one model, a guided image or a remix of several, a morph);
* :mod:`tghop.server.safety`: requests from another site or to another name (DNS rebinding)
  refused, 403;
* :mod:`tghop.server.materials`: whole materials (:class:`tghop.material.Material`): an albedo
  fitted with its maps, and a material's images as one answer of every map;
* :mod:`tghop.server.jobs`: the fit queue (a thread pool, progress through the library's
  callback, cancellation by an exception raised from it);
* ``static/``: the page (HTML, CSS and JavaScript; no build step, nothing fetched from
  the network).

Starlette, uvicorn and python-multipart come with the ``web`` extra
(``pip install 'tghop[web]'``); the rest of tghop never needs them, and importing these
modules does not import them either (:func:`~tghop.server.app.create_app` does, or
says in one line how to install them).
"""
