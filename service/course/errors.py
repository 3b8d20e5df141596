"""The error of class grading that stops a run: a fault of the teaching assistant's."""


class ClassError(Exception):
    """Input of the teaching assistant's that the batch cannot use: the run stops before any grading."""
