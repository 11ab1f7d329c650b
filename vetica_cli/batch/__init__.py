"""The batch machinery every command that runs many jobs shares (sweep, scan, advise), and
that knows no physics: launchers (:mod:`.launch`), the output lock (:mod:`.lock`), the
progress bar (:mod:`.progress`), content-addressed parts and the code fingerprint
(:mod:`.parts`, taking what to fingerprint as an argument) and one batch, one way
through (:mod:`.run`: output checks, signals, resume, parts removed on success)."""
