"""What a model of the IMU on its table is, independent of any log or estimator. One idea per
module:

- :mod:`.effects`          the effect vocabulary: names, units, typical magnitudes, regressors
- :mod:`.quantities`       values with units as files write them, converted to SI
- :mod:`.noise`            the composite noise of a channel (IEEE 952/1554 terms) and its block form
- :mod:`.flicker`          bias instability as a Gauss–Markov sum (the FMU's and the estimators')
- :mod:`.geometry`         the table's gimbal chain, base tilt, site: attitude and plate motion
- :mod:`.table_parameters` table effects of the vocabulary as fields of the geometry
- :mod:`.motion`           the plate's motion interpolated from logged angles, ideal increments
- :mod:`.result`           a calibrated model (``calbench-result/1``): values, covariance, provenance
- :mod:`.correct`          a raw log corrected by a calibrated model
"""
