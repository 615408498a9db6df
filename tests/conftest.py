"""Test-session set-up shared by every test module."""
import os

# One BLAS thread, as the command line asks for (hydroline.blas.single_threaded_blas), set
# before NumPy is first imported: the models' dense matrices are small (58-208 states), and
# extra BLAS threads on the suite's 2 cores only spin against each other (a two-axis bode or
# fit ran ~15x slower under pytest than from the command line). A count the user set is kept.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

# A compiled library not built yet is compiled before the run, in every test: the command line
# would otherwise build it in the background and run the first call on CVODES (and leave the
# variable set for the rest of the session), so that with an empty cache two runs of one rig in
# a test could take different integrators. Tests of the background build set it themselves.
os.environ.setdefault("HYDROLINE_BACKGROUND_BUILD", "0")
