#include "server/store/persister.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <set>

#include "common/core/error.h"
#include "server/store/checkpoint.h"
#include "server/store/journal.h"

namespace pf::server {
namespace fs = std::filesystem;

Persister::Persister(Scheduler& scheduler, SqliteStore& db, fs::path checkpoint_dir, const Clock& clock,
                     double checkpoint_interval_seconds)
    : scheduler_(scheduler),
      db_(db),
      checkpoint_dir_(std::move(checkpoint_dir)),
      clock_(clock),
      interval_(checkpoint_interval_seconds),
      last_checkpoint_(clock.Now()) {
  fs::create_directories(checkpoint_dir_);
}

Persister::~Persister() {
  Stop();
  std::lock_guard lock(flush_mu_);
  for (auto& [job, j] : journals_)
    if (j.fd >= 0) ::close(j.fd);
}

fs::path Persister::CheckpointFile(const fs::path& dir, const std::string& job_id) {
  return dir / (job_id + ".acc");
}
fs::path Persister::JournalFile(const fs::path& dir, const std::string& job_id) {
  return dir / (job_id + ".journal");
}

void Persister::Start() {
  std::lock_guard lock(mu_);
  if (started_ || stop_) return;
  started_ = true;
  thread_ = std::thread([this] { Loop(); });
}

void Persister::Stop() {
  {
    std::lock_guard lock(mu_);
    if (stop_) return;
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  try {
    Flush(true);
  } catch (const std::exception& e) {
    spdlog::error("final flush failed: {}", e.what());
  }
  ReleasePending();  // only left if the journal could not be written
}

void Persister::Abandon() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  ReleasePending();
}

void Persister::ReleasePending() {
  std::vector<Pending> left;
  {
    std::lock_guard lock(mu_);
    left.swap(pending_);
  }
  if (!left.empty()) spdlog::warn("{} results acknowledged without being journaled", left.size());
  for (Pending& p : left) p.ack();
}

void Persister::Wake() {
  {
    std::lock_guard lock(mu_);
    woken_ = true;
  }
  cv_.notify_all();
}

void Persister::JournalThenAck(const std::string& job_id, uint64_t task_id, std::span<const float> rgb_sums,
                               std::function<void()> ack) {
  {
    std::lock_guard lock(mu_);
    if (!stop_) {
      pending_.push_back(
          {job_id, task_id, std::vector<float>(rgb_sums.begin(), rgb_sums.end()), std::move(ack)});
      woken_ = true;
      cv_.notify_all();
      return;
    }
  }
  ack();
}

uint64_t Persister::checkpoints_written() const {
  std::lock_guard lock(mu_);
  return checkpoints_written_;
}

uint64_t Persister::journal_entries_written() const {
  std::lock_guard lock(mu_);
  return journal_entries_written_;
}

void Persister::FlushNow(bool checkpoints_due) {
  Flush(checkpoints_due);
}

void Persister::Loop() {
  std::unique_lock lock(mu_);
  while (!stop_) {
    // Rows and journal entries are written whenever something changed; checkpoints when due —
    // the timed wake-up catches merges that were not due at the last flush.
    const double timeout = interval_ > 0 ? interval_ : 1.0;
    cv_.wait_for(lock, std::chrono::duration<double>(timeout), [&] { return woken_ || stop_; });
    if (stop_) break;
    woken_ = false;
    lock.unlock();
    try {
      Flush(false);
    } catch (const std::exception& e) {
      spdlog::error("persisting failed (will retry): {}", e.what());
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    lock.lock();
  }
}

void Persister::WriteJournal(std::vector<Pending>& pending, std::vector<std::function<void()>>* acks,
                             std::vector<std::function<void()>>* after_checkpoint, bool* force_checkpoints) {
  std::set<std::string> touched, failed;
  for (Pending& p : pending) {
    if (failed.count(p.job_id)) {
      after_checkpoint->push_back(std::move(p.ack));
      continue;
    }
    JournalState& j = journals_[p.job_id];
    const fs::path file = JournalFile(checkpoint_dir_, p.job_id);
    if (j.fd < 0) j.fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    const std::string entry = EncodeJournalEntry(p.task_id, p.rgb_sums);
    size_t done = 0;
    while (j.fd >= 0 && done < entry.size()) {
      const ssize_t n = ::write(j.fd, entry.data() + done, entry.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      done += size_t(n);
    }
    if (done != entry.size()) {
      spdlog::error("job {}: journal {} not writable ({}); checkpointing instead", p.job_id, file.string(),
                    std::strerror(errno));
      failed.insert(p.job_id);
      *force_checkpoints = true;
      after_checkpoint->push_back(std::move(p.ack));
      continue;
    }
    j.bytes += entry.size();
    if (j.bytes >= kJournalSnapshotBytes) *force_checkpoints = true;
    touched.insert(p.job_id);
    acks->push_back(std::move(p.ack));
  }
  for (const std::string& job : touched) {
    JournalState& j = journals_[job];
    if (failed.count(job) || ::fdatasync(j.fd) != 0) {
      if (!failed.count(job)) spdlog::error("job {}: journal fdatasync failed; checkpointing instead", job);
      failed.insert(job);
      *force_checkpoints = true;
    }
  }
  if (!failed.empty()) {
    // Some entries are not durable: answer everything of this group after the checkpoint.
    for (auto& ack : *acks) after_checkpoint->push_back(std::move(ack));
    acks->clear();
  }
  std::lock_guard lock(mu_);
  journal_entries_written_ += pending.size();
}

void Persister::TruncateJournal(const std::string& job_id) {
  auto it = journals_.find(job_id);
  if (it != journals_.end() && it->second.fd >= 0) {
    if (::ftruncate(it->second.fd, 0) == 0) ::fdatasync(it->second.fd);
    it->second.bytes = 0;
    return;
  }
  std::error_code ec;
  const fs::path file = JournalFile(checkpoint_dir_, job_id);
  if (fs::exists(file, ec)) fs::resize_file(file, 0, ec);
}

void Persister::CloseJournal(const std::string& job_id, bool remove) {
  auto it = journals_.find(job_id);
  if (it != journals_.end()) {
    if (it->second.fd >= 0) ::close(it->second.fd);
    journals_.erase(it);
  }
  if (remove) {
    std::error_code ec;
    fs::remove(JournalFile(checkpoint_dir_, job_id), ec);
  }
}

void Persister::Flush(bool force_checkpoints) {
  std::lock_guard flush_lock(flush_mu_);
  std::vector<Pending> pending;
  {
    std::lock_guard lock(mu_);
    pending.swap(pending_);
  }
  // 1. Journal.
  std::vector<std::function<void()>> acks, after_checkpoint;
  if (!pending.empty()) WriteJournal(pending, &acks, &after_checkpoint, &force_checkpoints);
  for (auto& ack : acks) ack();

  // 2. Checkpoints.
  const double now = clock_.Now();
  bool due = force_checkpoints;
  {
    std::lock_guard lock(mu_);
    if (interval_ > 0)
      due = due || now - last_checkpoint_ >= interval_;
    else
      due = due || now - last_checkpoint_ >= kSnapshotSeconds;
    if (due) last_checkpoint_ = now;
  }
  PersistBatch batch = scheduler_.CollectPersistBatch(due);
  size_t written = 0;
  std::set<std::string> failed_checkpoints;
  for (const Checkpoint& cp : batch.checkpoints) {
    try {
      WriteCheckpointFile(CheckpointFile(cp.job_id), cp);
      scheduler_.CheckpointWritten(cp.job_id, cp.merge_seq, CheckpointFile(cp.job_id).string());
      ++written;
      if (durable_acks()) TruncateJournal(cp.job_id);
      spdlog::debug("job {}: checkpoint of {} merges written", cp.job_id, cp.merged_task_ids.size());
    } catch (const std::exception& e) {
      spdlog::error("job {}: checkpoint failed: {}", cp.job_id, e.what());
      scheduler_.CheckpointFailed(cp.job_id, cp.merge_seq);
      failed_checkpoints.insert(cp.job_id);
    }
  }
  {
    std::lock_guard lock(mu_);
    checkpoints_written_ += written;
  }
  for (auto& ack : after_checkpoint) ack();

  // 3. Rows.
  try {
    db_.Apply(batch.jobs, batch.tasks);
  } catch (...) {
    scheduler_.RestoreDirty(batch);  // written with the next flush
    throw;
  }
  // A finished job's final checkpoint is on disk (CollectPersistBatch hands it out with the
  // final row): its journal is no longer needed.
  for (const JobRow& row : batch.jobs)
    if (IsTerminal(row.state) && !failed_checkpoints.count(row.job_id))
      CloseJournal(row.job_id, /*remove=*/true);
}

}  // namespace pf::server
