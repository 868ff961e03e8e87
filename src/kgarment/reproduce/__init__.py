"""Reproducing the paper: experiments, baselines, evaluation and the report (``kgarment reproduce``)."""
