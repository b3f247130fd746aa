"""System-level calibration: strapdown navigation in ENU from IMU increments, alignment, and an
error-state Kalman filter whose states are the 9 navigation errors plus any chosen effects of the
vocabulary (components.model.effects), observed through the navigation velocity on a stationary base
(domain.md §6 seeds 001/003, §7). One idea per module:

- :mod:`.earth`        site constants (gravity, Earth rate, radii) at a fixed latitude
- :mod:`.strapdown`    attitude (two-sample coning) and velocity (two-sample sculling) updates
- :mod:`.alignment`    coarse (analytic) and fine (zero-velocity KF) alignment
- :mod:`.sensor`       per-sample effect regressors evaluated on the IMU's own measured motion
- :mod:`.kf`           the error-state filter: propagation, updates, feedback, passes, RTS
- :mod:`.configs`      ready-made configurations (seed 001, seed 003, PSINS-style 19 positions)
- :mod:`.observability` piece-wise constant system (PWCS) analysis with SVD
"""
