"""The HTTP service: the app factory, its routers, middleware, request models and the render job store.

Imported as ``service.http`` only (absolute imports): the name never stands alone on ``sys.path``, so the
standard library's :mod:`http` stays the one that uvicorn and starlette import."""
