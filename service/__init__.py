"""phongray over HTTP, and the command line."""
