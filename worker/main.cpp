// pf-worker — a photonfarm render worker. Pulls tasks from a pf-coordinator, renders them on all
// its threads and reports the pixel sums of each task's subset (worker_main.h: options, signals,
// exit codes; worker.h: the state machine).
#include "worker/worker_main.h"

int main(int argc, char** argv) {
  return pf::worker::RunWorkerProcess(argc, argv, nullptr);
}
