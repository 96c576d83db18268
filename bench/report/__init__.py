"""Renderers of the analysis results, all in one place: the analysis returns data, these turn it
into text (:mod:`~bench.report.text`), versioned JSON (:mod:`~bench.report.json_out`, from the
document's types in :mod:`~bench.report.analysis_document`), matplotlib
figures (:mod:`~bench.report.figures`) and a self-contained HTML page (:mod:`~bench.report.html`).
"""
