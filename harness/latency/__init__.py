"""Sensing latency and sampling of the feedback loops: the analysis.

- :mod:`.loop`: :class:`~.loop.FeedbackLoop`, a plant closed by u = K x_s + KI z;
- :mod:`.continuous`: model (a), a continuous pure delay: crossing frequencies and delay
  margins of the characteristic quasi-polynomial;
- :mod:`.spectral`: the second method for (a), Chebyshev collocation of the delay equation;
- :mod:`.sampled`: model (b), sampling with a delay (whole or fractional sample periods):
  the exact augmented discrete-time loop, its margins, responses and verdict maps;
- :mod:`.designs`: the four designs compared (Eq. 27, the stabilising one, LQR, PI on roll);
- :mod:`.identify`: the delayed loop's transition matrix identified from co-simulated runs;
- :mod:`.report`: the tables of docs/latency.md.

Time is in wing beats (t+ = t n) and states are non-dimensional (x+) throughout; the
tables convert to ms at n = 164 Hz.
"""
