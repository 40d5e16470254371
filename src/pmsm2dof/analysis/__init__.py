"""Design and analysis of the speed controller: no simulation, no I/O.

:mod:`.design` designs the 2DOF PI (eq 9-13) and its linear loop (eq 2-8), :mod:`.discretize`
samples it (Table 1, eq 14, 15) with the coefficients the C controller computes,
:mod:`.margins` finds stability margins, :mod:`.stepresponse` the step-response figures of a
linear loop at any time scale, and :mod:`.codegen` the C text of a configuration.
"""
