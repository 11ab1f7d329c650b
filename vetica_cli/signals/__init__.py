"""Signal processing on recorded samples: force reconstruction and the spectral
derivative (:mod:`.spectral`), tap finding (:mod:`.taps`).  Plain arrays in and out."""
