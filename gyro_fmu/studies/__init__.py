"""Studies over many runs: the Dask plumbing the lot studies share (tasks.py), and the
measures of a rate record they share: the Allan deviation (allan.py), the response to
stepped sines (response.py)."""
