"""The turntable FMU's sources (C) and what Python needs to know of them."""

# the servo controller's rate: every communication step is a whole number of its periods (the
# FMU refuses others at its first step); design_servo designs the default gains for it
CONTROL_RATE_HZ = 2000.0
