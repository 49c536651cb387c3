#include "client/progress.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace pf {

std::string FormatDuration(double s) {
  if (s < 0) return "?";
  if (s < 60) return fmt::format("{:.1f} s", s);
  if (s < 3600) return fmt::format("{} min {} s", int(s / 60), int(s) % 60);
  return fmt::format("{} h {} min", int(s / 3600), (int(s) % 3600) / 60);
}

ProgressBar::ProgressBar(const std::atomic<uint64_t>& done, uint64_t total, bool enabled)
    : done_(done), total_(total), enabled_(enabled), tty_(isatty(fileno(stderr))) {
  if (enabled_) thread_ = std::thread([this] { Run(); });
}

void ProgressBar::Finish() {
  if (!thread_.joinable()) return;
  stop_ = true;
  thread_.join();
  Draw(true);
  if (tty_) std::fputc('\n', stderr);
}

void ProgressBar::Run() {
  while (!stop_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(tty_ ? 200 : 100));
    Draw(false);
  }
}

void ProgressBar::Draw(bool final) {
  const uint64_t done = std::min(done_.load(), total_);
  const double frac = total_ ? double(done) / double(total_) : 1.0;
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  if (tty_) {
    constexpr int kWidth = 40;
    std::string bar(size_t(frac * kWidth), '#');
    bar.resize(kWidth, '.');
    const double eta = frac > 0 ? elapsed * (1.0 - frac) / frac : 0.0;
    // \033[K erases the rest of the line: a shorter line leaves no stray characters behind.
    std::fprintf(stderr, "\r[%s] %5.1f%%  %6.1fs elapsed  ETA %6.1fs\033[K", bar.c_str(), 100.0 * frac,
                 elapsed, eta);
    std::fflush(stderr);
  } else {
    const int decile = int(frac * 10.0);
    if (decile > last_decile_ || final) {
      last_decile_ = decile;
      if (!final || decile < 10) std::fprintf(stderr, "progress %3d%% after %.1fs\n", decile * 10, elapsed);
    }
  }
}

FarmProgress::FarmProgress(bool enabled) : enabled_(enabled), tty_(isatty(fileno(stderr))) {}

void FarmProgress::Update(const photonfarm::v1::JobStatus& s) {
  if (!enabled_) return;
  if (s.storage_error() != last_storage_error_) {
    // Said once per change, on its own line: the coordinator's disk is full or failing.
    last_storage_error_ = s.storage_error();
    if (drawn_) std::fputc('\n', stderr);
    if (!s.storage_error().empty())
      std::fprintf(stderr, "coordinator storage%s: %s\n", s.paused_for_storage() ? " (job paused)" : "",
                   s.storage_error().c_str());
    else
      std::fprintf(stderr, "coordinator storage: stored again\n");
  }
  const double frac = std::clamp(s.progress(), 0.0, 1.0);  // of the work (docs/farm.md, "ETA")
  const std::string noise =
      s.estimated_noise_rms() >= 0 ? fmt::format("{:.4g}", s.estimated_noise_rms()) : "-";
  const std::string eta = s.eta_seconds() >= 0 ? FormatDuration(s.eta_seconds()) : "?";
  // An animation: how many of its frames are complete (docs/farm.md "Animation").
  std::string frames;
  if (s.frames_size() > 0) {
    const auto complete = std::count_if(s.frames().begin(), s.frames().end(), [](const auto& f) {
      return f.tasks_total() > 0 && f.tasks_done() == f.tasks_total();
    });
    frames = fmt::format("  frames {}/{}", complete, s.frames_size());
  }
  if (tty_) {
    constexpr int kWidth = 30;
    std::string bar(size_t(frac * kWidth), '#');
    bar.resize(kWidth, '.');
    std::fprintf(stderr, "\r[%s] %5.1f%%  %llu/%llu tasks%s  %llu running  %s  ETA %s  noise %s\033[K",
                 bar.c_str(), 100.0 * frac, (unsigned long long)s.tasks_done(),
                 (unsigned long long)s.tasks_total(), frames.c_str(), (unsigned long long)s.tasks_running(),
                 FormatDuration(s.elapsed_seconds()).c_str(), eta.c_str(), noise.c_str());
    std::fflush(stderr);
    drawn_ = true;
  } else {
    const int decile = int(frac * 10.0);
    if (decile > last_decile_ || s.state() != last_state_) {
      last_decile_ = decile;
      std::fprintf(stderr, "progress %5.1f%%  %llu/%llu tasks%s  elapsed %s  ETA %s  noise %s\n",
                   100.0 * frac, (unsigned long long)s.tasks_done(), (unsigned long long)s.tasks_total(),
                   frames.c_str(), FormatDuration(s.elapsed_seconds()).c_str(), eta.c_str(), noise.c_str());
    }
  }
  last_state_ = s.state();
}

void FarmProgress::Finish() {
  if (drawn_ && tty_) std::fputc('\n', stderr);
  drawn_ = false;
}

}  // namespace pf
