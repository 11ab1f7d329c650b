"""Measured force curves with a dwell (stress relaxation, creep) read through afmformats and
fitted with the viscoelastic Hertz model (Lee–Radok, Prony series): reading (:mod:`.read`),
the forward model (:mod:`.leeradok`), the fit and model selection (:mod:`.fit`), the batch,
table and figures (:mod:`.batch`, :mod:`.figures`), and the afmformats example's analysis for
comparison (:mod:`.reference`).  The parameters are the ``hertz`` surface model's: ``e_inf``,
``e_i`` [Pa], ``tau_i`` [s], ``nu``."""
