"""The layered BSDF (Guo, Hašan, Zhao 2018) as compiled per-lane code: each lane walks its own
stack to its own end.

Modules (import them through ``backend.kernels``, which configures the kernel cache first):
* ``phase``   phase functions of the slab media (the kinds of ``phase_layout.KINDS``, with Guo's
              fiber microflakes' projected-area table), per lane;
* ``iface``   the interfaces as the walk needs them: sample and eval with both sampling
              densities (importance transport), per-interface normal maps;
* ``table``   the stack table's layout (one per scene), its assembly and ``bind`` (a lane's stack
              at its (u, v)); backend/layered/stack_table.py builds it from the materials;
* ``walk``    the random walk through a bound stack, with its MIS records;
* ``estimators``  eval (bidirectional, unidirectional), the approximate and the stochastic pdf,
              sample, the integrator's combined light connection + continuation, albedo;
* ``batch``   array entry points for NumPy callers (``backend/layered``: the BSDF inspector,
              tests) — loops over lanes calling the same per-lane code as the integrator.

Compiler options: ``error_model="numpy"`` (no division-by-zero checks; every division that
matters is guarded) but no ``fastmath``. With value-changing fast-math flags (contraction,
reassociation) a render in a process that had first loaded the inspector's ``run`` kernel
differed in the last bit from the same render in a fresh process (caught by the bit-identity
test; most likely a shared function's symbol resolved to ``run``'s copy, optimised and rounded
differently). Without them every compiled copy computes the same IEEE results (measured cost of
dropping them: within the run-to-run noise).
"""
