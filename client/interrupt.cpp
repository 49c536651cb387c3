#include "client/interrupt.h"

#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <mutex>
#include <thread>

namespace pf {
namespace {

std::mutex g_mutex;
std::function<void(int)> g_handler;
std::atomic<int> g_count{0};

}  // namespace

void InstallInterruptHandling() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  std::thread([set] {
    while (true) {
      int sig = 0;
      if (sigwait(&set, &sig) != 0) continue;
      const int n = ++g_count;
      // Called under the lock: once SetInterruptHandler returns, the old handler (and what it
      // refers to) is no longer in use.
      std::lock_guard lock(g_mutex);
      if (!g_handler) {
        std::fputs("\ninterrupted\n", stderr);
        std::fflush(nullptr);
        _exit(130);
      }
      g_handler(n);
    }
  }).detach();
}

void SetInterruptHandler(std::function<void(int)> handler) {
  std::lock_guard lock(g_mutex);
  g_handler = std::move(handler);
}

bool Interrupted() {
  return g_count.load() > 0;
}

}  // namespace pf
