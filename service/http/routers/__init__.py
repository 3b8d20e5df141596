"""The service's routers, one per concept: a scene's render and validation (:mod:`.render`), a grade
(:mod:`.grade`), the schema and a worker's health (:mod:`.status`), the playground and the API's pages
(:mod:`.playground`)."""
