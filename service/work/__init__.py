"""The work every front end shares: a scene graded, written once for the command line, HTTP and class grading; the
service's renders and grades as jobs, with their cache, render slots and cancellation."""
