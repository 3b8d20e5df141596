"""The forms class grading writes, where a dict is the shape of the file itself: a report's row as report.json
and the CSVs hold it, what the resume journal stamps a kept grade with, and Gradescope's results.json.  Every
other step carries a record (:mod:`.records`)."""

from __future__ import annotations

from typing import Any

#: a row as JSON and CSV hold it: the report's (:meth:`~.records.Row.row`, its keys the report's columns), or a
#: grade's as the resume journal keeps it (:func:`~.rows.kept_row`, the columns a grade decides)
ReportRow = dict[str, Any]
#: what a kept grade is the grade of, as the journal writes it (:func:`~.journal.stamp`)
Stamp = dict[str, Any]
#: a JSON object of Gradescope's results.json (the file, or one of its tests)
Results = dict[str, Any]
