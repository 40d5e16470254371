"""Independent derivations the tests check the code against (never imported by pmsm2dof)."""
