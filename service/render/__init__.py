"""Where a render runs (here, over processes, or on a Dask cluster), the key a scene's renders are cached under, and
render passes written as files."""
