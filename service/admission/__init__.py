"""What a request may be: the service's limits checked before and as a scene renders, and its work priced before it
runs."""
