"""The web server's route handlers, by what they serve (the table is
:func:`tghop.server.app.create_app`'s; docs/serve.md describes each route):

* :mod:`~tghop.server.routes.fit`: ``POST /api/models`` (a fit) and ``/api/jobs/{job}``;
* :mod:`~tghop.server.routes.models`: a model's summary, download and upload;
* :mod:`~tghop.server.routes.images`: generation from one model, a painted guide or remix, a morph;
* :mod:`~tghop.server.routes.fill`: inpaint and extend;
* :mod:`~tghop.server.routes.cooc`: co-occurrence checkpoints.

Each handler is ``async def handler(server, request)``: ``server`` is the
:class:`~tghop.server.core.Server` (the cache, the queues, the bounds), bound by ``create_app``.
"""
