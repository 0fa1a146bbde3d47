// `hmc_slurm_cluster DIR COMMAND [ARG...]`: starts the tests' one-node SLURM
// cluster (tests/slurm_fixture.h) in DIR, runs COMMAND with SLURM_CONF
// pointing at it, stops the cluster and exits with COMMAND's exit code. For
// measuring `hmc batch --scheduler slurm` by hand (docs/farm.md).
#include <cstdio>
#include <string>
#include <vector>

#include "pipeline/subprocess.h"
#include "tests/slurm_fixture.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: hmc_slurm_cluster DIR COMMAND [ARG...]\n");
    return 2;
  }
  const std::string missing = hmc::SlurmCluster::Missing();
  if (!missing.empty()) {
    std::fprintf(stderr, "hmc_slurm_cluster: %s not installed\n", missing.c_str());
    return 2;
  }
  hmc::SlurmCluster cluster(argv[1]);
  if (!cluster.Ok()) {
    std::fprintf(stderr, "hmc_slurm_cluster: %s\n", cluster.Error().c_str());
    return 1;
  }
  return hmc::WaitProcess(
      hmc::StartProcess(std::vector<std::string>(argv + 2, argv + argc), {}, ""));
}
