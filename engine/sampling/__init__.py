"""Random and quasi-random numbers (Owen-scrambled Sobol') and the warps that turn them into directions and points."""
