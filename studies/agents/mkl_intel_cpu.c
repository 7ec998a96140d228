/* Tell Intel MKL (torch's BLAS) that the CPU is an Intel one, so it takes the kernels it takes there.
 *
 * For checking only: a shipped model trained where MKL took its Intel path is retrained bit for bit on
 * another CPU with this preloaded (training/NOTES.md, "Same seed, same weights"):
 *
 *     gcc -shared -fPIC -o /tmp/mkl_intel_cpu.so studies/agents/mkl_intel_cpu.c
 *     LD_PRELOAD=/tmp/mkl_intel_cpu.so marine-fdi train --algo classifier --hyperparams robust --seed 0 --out /tmp/c0
 *     cmp /tmp/c0/model.pt training/models/classifier/seed0/model.pt
 *
 * It overrides two internal MKL symbols (the CPU-vendor test); nothing of the package uses it. */
int mkl_serv_intel_cpu_true(void) { return 1; }
int mkl_serv_intel_cpu(void) { return 1; }
