"""The offline stage: fitness, PSO, one experiment, the DOE, the regression and the coefficients file."""
