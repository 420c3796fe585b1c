"""What the loop and the tracker show: figures, HTML pages and the tracker's report.

* :mod:`twin.report.figures`: the figures of a comparison and of a record (and :func:`~twin.report.figures.pyplot`,
  the one way the package opens matplotlib);
* :mod:`twin.report.html`: a report page from Markdown, with its figures, written atomically;
* :mod:`twin.report.tracking`: the tracker's report over its records.
"""
