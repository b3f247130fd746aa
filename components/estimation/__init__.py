"""Estimation of a model's parameters from a log. One idea per module:

- :mod:`.log_data`     what the estimators need from a log, in SI
- :mod:`.blocks`       observation blocks: 1 s static chunks and rest-to-rest moves
- :mod:`.rest_angles`  the encoder's count: how far the table really rests from its reading
- :mod:`.design`       the observation model (stacked block rows, weights), shared by all below
- :mod:`.lsq`          general weighted least squares over any effects (Gauss–Newton on the table)
- :mod:`.crb`          the Cramér–Rao bound of a schedule for a noise model
"""
