"""QuasiTune numerics: reference data, features, GPR, GMM/GMR, KMP, quasi-stiffness fit."""
