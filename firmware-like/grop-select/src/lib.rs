//! GROP selection core: utility U = R*F - C, closed-form task-level feasibility, Smp sampling, argmax (no_std, no heap).
