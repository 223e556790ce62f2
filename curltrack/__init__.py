"""curltrack: measure how curling rocks move.

Pipeline (data flows one way)::

    video -> calib (thread grid) -> track (markers, stops) -> series (SHOT.csv)
          -> fit (the paper's closed forms) / discover (model vs. data)

``physics`` holds the one model core (closed forms, equations of motion, effect
terms) shared by ``fit``, ``simulate``, ``render`` and ``discover``.
"""

__version__ = "0.1.0"
