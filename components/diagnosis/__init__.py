"""The model against the measurement, and what is missing. One idea per module:

- :mod:`.compare`          residuals, χ²/dof of block sums, fit, whiteness, where the model fails
- :mod:`.diagnose`         which effect of the vocabulary is missing (refit and test each candidate)
- :mod:`.ladder`           the ladder: χ²/dof and RMS per model version as effects are added
- :mod:`.noise_id`         which noise terms a log shows (Allan stage + likelihood stage); adding one
- :mod:`.noise_choice`     which noise model a command uses, from the user's --noise, said aloud
- :mod:`.residual_export`  per-sample residuals as CSV in the log's units
- :mod:`.report`           the self-contained HTML report
"""
