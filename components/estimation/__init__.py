"""Estimation of a model's parameters from a log. One idea per module:

- :mod:`.log_data`     what the estimators need from a log, in SI
- :mod:`.blocks`       observation blocks: 1 s static chunks and rest-to-rest moves
- :mod:`.rest_angles`  the encoder's count: how far the table really rests from its reading
- :mod:`.design`       the observation model (stacked block rows, weights), shared by all below
- :mod:`.chunks`       the block rows a chunk of the log at a time, on forked worker processes
- :mod:`.whitening`    generalised least squares in linear time: the block rows whitened by a
                       Kalman filter of the noise model
- :mod:`.allan`        pooled overlapping Allan variance of residuals, with degrees of freedom
- :mod:`.noise_fit`    the fast noise terms fitted to the Allan variance (bootstrap σ)
- :mod:`.noise_likelihood` the slow noise terms by (restricted) maximum likelihood on the block rows
- :mod:`.lsq`          general weighted least squares over any effects (Gauss–Newton on the table)
- :mod:`.crb`          the Cramér–Rao bound of a schedule for a noise model
- :mod:`.positions`    calibration without a turntable: rests of unknown attitude, turns of a
                       known angle about a body axis (docs/positions.md); its entry point, in
                       steps: :mod:`.positions_input` (the segments described and sorted),
                       :mod:`.positions_observations` (the rows), :mod:`.positions_model` (their
                       prediction and Jacobian), :mod:`.positions_solve` (Gauss–Newton,
                       covariance, what is undetermined), :mod:`.positions_result` (the fit)
"""
