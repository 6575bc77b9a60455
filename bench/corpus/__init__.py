"""The random-part corpus that judges recon (issues 22, 23, 24): generator, regimes, runner."""
