#pragma once
// pf-worker as a process: parses the command line, sets up logging and signals, runs a Worker
// until it is stopped and exits with the documented code (worker_main.cpp). pf-worker injects no
// faults; a test binary injects its own (worker_faults.h) and is otherwise the same process.

#include <memory>

#include "worker/worker_faults.h"

namespace pf::worker {

int RunWorkerProcess(int argc, char** argv, std::shared_ptr<WorkerFaults> faults);

}  // namespace pf::worker
