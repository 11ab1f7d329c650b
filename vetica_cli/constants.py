"""Physical constants and shared thresholds used in more than one place (SI)."""

EV = 1.602176634e-19  # [J] one electronvolt (exact, SI 2019); energies are reported in eV
TIP_RADIUS = 10e-9  # [m] tip radius R of the thesis (table 1): config default and the fit's fallback
