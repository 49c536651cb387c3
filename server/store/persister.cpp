#include "server/store/persister.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <iterator>
#include <set>
#include <tuple>

#include "common/core/error.h"
#include "server/store/checkpoint.h"

namespace pf::server {
namespace fs = std::filesystem;

Persister::Persister(PersistSource& source, JobStore& db, fs::path checkpoint_dir, const Clock& clock,
                     double checkpoint_interval_seconds, FileLayer& files)
    : source_(source),
      db_(db),
      checkpoint_dir_(std::move(checkpoint_dir)),
      clock_(clock),
      interval_(checkpoint_interval_seconds),
      files_(files),
      last_checkpoint_(clock.Now()) {
  fs::create_directories(checkpoint_dir_);
}

Persister::~Persister() {
  Stop();
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

bool Persister::Stop() {
  {
    std::lock_guard lock(mu_);
    if (stop_) return stopped_ok_;
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  bool ok = false;
  try {
    ok = Flush(true);
  } catch (const std::exception& e) {
    spdlog::error("final flush failed: {}", e.what());
  }
  if (!ok)
    spdlog::error(
        "final flush incomplete: some results, checkpoints or rows are not stored (see above); the tasks "
        "they hold are re-run at the next start");
  ReleasePending("the coordinator stopped before the result was stored");
  std::lock_guard lock(mu_);
  stopped_ok_ = ok;
  return ok;
}

void Persister::Abandon() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
    stopped_ok_ = false;  // nothing was flushed: a later Stop() must not say everything was stored
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  ReleasePending("the coordinator stopped before the result was stored");
}

void Persister::ReleasePending(const std::string& why) {
  std::vector<Pending> left;
  {
    std::lock_guard lock(mu_);
    left.swap(pending_);
  }
  if (!left.empty()) spdlog::warn("{} results answered as not stored: {}", left.size(), why);
  for (Pending& p : left) p.ack(why);
}

void Persister::Wake() {
  {
    std::lock_guard lock(mu_);
    woken_ = true;
  }
  cv_.notify_all();
}

void Persister::JournalThenAck(const std::string& job_id, uint64_t task_id, uint32_t epoch,
                               uint64_t merge_seq, std::span<const float> rgb_sums, Ack ack) {
  {
    std::lock_guard lock(mu_);
    if (!stop_) {
      pending_.push_back({job_id, task_id, epoch, merge_seq,
                          std::vector<float>(rgb_sums.begin(), rgb_sums.end()), std::move(ack)});
      woken_ = true;
      cv_.notify_all();
      return;
    }
  }
  ack("the coordinator is stopping");
}

uint64_t Persister::checkpoints_written() const {
  std::lock_guard lock(mu_);
  return checkpoints_written_;
}

uint64_t Persister::journal_entries_written() const {
  std::lock_guard lock(mu_);
  return journal_entries_written_;
}

bool Persister::FlushNow(bool checkpoints_due) {
  return Flush(checkpoints_due);
}

void Persister::Loop() {
  std::unique_lock lock(mu_);
  while (!stop_) {
    // Rows and journal entries are written whenever something changed; checkpoints when due —
    // the timed wake-up catches merges that were not due at the last flush, and retries what
    // failed (D4).
    const double timeout = interval_ > 0 ? std::min(interval_, 1.0) : 1.0;
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

JournalWriter& Persister::Journal(const std::string& job_id) {
  std::unique_ptr<JournalWriter>& j = journals_[job_id];
  if (!j) j = std::make_unique<JournalWriter>(JournalFile(checkpoint_dir_, job_id), files_);
  return *j;
}

namespace {

constexpr const char* kDropped =
    "the job started again from nothing after a wrong result; this one is not in it";

// Answers every acknowledgement still unanswered when a flush ends by an exception (an
// allocation failing while a checkpoint is serialised, say): their CompleteTask calls must finish,
// as "not stored", or the RPCs would hang and a graceful stop with them.
template <typename... Lists>
struct AnswerLeftovers {
  std::tuple<Lists*...> lists;
  ~AnswerLeftovers() {
    const auto answer = [](auto* list) {
      for (auto& item : *list) {
        auto& ack = AckOf(item);
        if (!ack) continue;
        try {
          ack("not stored: the coordinator's flush failed");
        } catch (...) {
        }
        ack = nullptr;
      }
    };
    std::apply([&](auto*... l) { (answer(l), ...); }, lists);
  }
  static Persister::Ack& AckOf(Persister::Ack& ack) { return ack; }
  template <typename T>
  static Persister::Ack& AckOf(T& item) {
    return item.ack;
  }
};

void Answer(Persister::Ack& ack, const std::string& not_stored) {
  if (!ack) return;
  Persister::Ack a = std::move(ack);
  ack = nullptr;
  a(not_stored);
}

}  // namespace

bool Persister::WriteJournal(std::vector<Pending>& pending, std::vector<Ack>* stored,
                             std::vector<Waiting>* waiting) {
  // Appends per job, then one sync per job; a job whose journal fails falls back to a checkpoint
  // for all of this flush's results (the appended ones may be lost with the failed sync).
  std::map<std::string, std::string> failed;
  std::map<std::string, std::vector<size_t>> appended;
  for (size_t i = 0; i < pending.size(); ++i) {
    Pending& p = pending[i];
    if (p.epoch != source_.JobEpoch(p.job_id)) {
      // Merged before the job started again from nothing (a convicted worker): its result is
      // not in the image any more and must never come back from the journal.
      Answer(p.ack, kDropped);
      continue;
    }
    if (p.merge_seq <= source_.StoredMergeSeq(p.job_id)) {
      // A checkpoint stored since the merge holds it (the persister may flush between a merge
      // and its JournalThenAck): stored, and nothing to append (a finished job has no journal).
      stored->push_back(std::move(p.ack));
      p.ack = nullptr;
      continue;
    }
    if (failed.count(p.job_id)) continue;
    JournalWriter& journal = Journal(p.job_id);
    std::string problem;
    if (journal.Append(EncodeJournalEntry(p.task_id, p.epoch, p.rgb_sums), &problem))
      appended[p.job_id].push_back(i);
    else
      failed[p.job_id] = problem;
  }
  std::vector<uint64_t> ids;
  for (auto& [job, indices] : appended) {
    std::string problem;
    if (failed.count(job) || !Journal(job).Sync(&problem)) {
      if (!failed.count(job)) failed[job] = problem;
      continue;
    }
    ids.clear();
    for (size_t i : indices) ids.push_back(pending[i].task_id);
    source_.ResultsJournaled(job, ids);
    for (size_t i : indices) {
      stored->push_back(std::move(pending[i].ack));
      pending[i].ack = nullptr;
    }
    if (Journal(job).bytes_since_reset() >= kJournalSnapshotBytes) source_.ForceCheckpoint(job);
  }
  for (const auto& [job, problem] : failed) {
    spdlog::error("job {}: results not journaled ({}); checkpointing instead", job, problem);
    source_.ForceCheckpoint(job);
  }
  for (Pending& p : pending)
    if (auto f = failed.find(p.job_id); f != failed.end() && p.ack) {
      waiting->push_back({p.job_id, p.epoch, p.merge_seq, f->second, std::move(p.ack)});
      p.ack = nullptr;
    }
  std::lock_guard lock(mu_);
  journal_entries_written_ += stored->size();
  return failed.empty();
}

bool Persister::Flush(bool force_checkpoints) {
  std::lock_guard flush_lock(flush_mu_);
  bool ok = true;
  std::vector<Pending> pending;
  {
    std::lock_guard lock(mu_);
    pending.swap(pending_);
  }
  // 1. Journal.
  std::vector<Ack> stored;
  std::vector<Waiting> waiting;
  const AnswerLeftovers<std::vector<Pending>, std::vector<Ack>, std::vector<Waiting>> leftovers{
      {&pending, &stored, &waiting}};
  if (!pending.empty()) ok = WriteJournal(pending, &stored, &waiting) && ok;
  for (Ack& ack : stored) Answer(ack, "");

  // 2. Checkpoints.
  const double now = clock_.Now();
  bool due = force_checkpoints;
  {
    std::lock_guard lock(mu_);
    due = due || now - last_checkpoint_ >= (interval_ > 0 ? interval_ : kSnapshotSeconds);
    if (due) last_checkpoint_ = now;
  }
  std::set<std::string> checkpointed;
  std::map<std::string, std::string> not_checkpointed;
  size_t written = 0;
  for (const Checkpoint& cp : source_.CollectCheckpoints(due)) {
    const fs::path file = CheckpointFile(cp.job_id);
    try {
      const CheckpointSeal seal = WriteCheckpointFile(file, cp, files_);
      source_.CheckpointStored(cp, seal, file.string());
      checkpointed.insert(cp.job_id);
      ++written;
      spdlog::debug("job {}: checkpoint of {} merges written", cp.job_id, cp.merged_task_ids.size());
    } catch (const std::exception& e) {
      spdlog::error("job {}: checkpoint not stored: {}", cp.job_id, e.what());
      source_.CheckpointNotStored(cp.job_id, cp.merge_seq, e.what());
      not_checkpointed[cp.job_id] = e.what();
      ok = false;
      continue;
    }
    // D3: the journal is emptied only now that a verified checkpoint holds all of it.
    if (durable_acks()) {
      std::string problem;
      if (!Journal(cp.job_id).Reset(&problem))
        spdlog::warn(
            "job {}: journal not emptied after its checkpoint ({}); its entries are in the checkpoint",
            cp.job_id, problem);
    }
  }
  {
    std::lock_guard lock(mu_);
    checkpoints_written_ += written;
  }
  for (Waiting& w : waiting) {
    if (w.epoch != source_.JobEpoch(w.job_id)) {
      Answer(w.ack, kDropped);
    } else if (w.merge_seq <= source_.StoredMergeSeq(w.job_id)) {
      Answer(w.ack, "");  // a stored checkpoint holds it (this flush's, or an earlier one)
    } else {
      auto f = not_checkpointed.find(w.job_id);
      const std::string why = w.journal_problem + "; checkpoint: " +
                              (f != not_checkpointed.end() ? f->second : std::string("not written"));
      source_.ResultsNotStored(w.job_id, why);
      Answer(w.ack, why);
    }
  }

  // 3. Rows.
  const RowBatch rows = source_.CollectRows();
  if (rows.empty()) {
    CloseJournalsBeyondTheCap();
    return ok;
  }
  try {
    db_.Apply(rows.jobs, rows.tasks);
  } catch (const std::exception& e) {
    spdlog::error("rows not stored ({} jobs, {} tasks): {}", rows.jobs.size(), rows.tasks.size(), e.what());
    source_.RowsNotStored(rows, e.what());
    return false;
  }
  source_.RowsStored(rows);
  // A finished job's final row is written only after its final checkpoint was stored (D2): its
  // journal is no longer needed.
  for (const JobRow& row : rows.jobs) {
    if (!IsTerminal(row.state)) continue;
    if (auto it = journals_.find(row.job_id); it != journals_.end()) {
      it->second->Remove();
      journals_.erase(it);
    } else {
      files_.Unlink(JournalFile(checkpoint_dir_, row.job_id).c_str());
    }
  }
  CloseJournalsBeyondTheCap();
  return ok;
}

uint64_t Persister::DeleteJob(const std::string& job_id, const std::function<void()>& forget) {
  std::lock_guard flush_lock(flush_mu_);
  db_.DeleteJob(job_id);
  forget();
  std::vector<Pending> dropped;
  {
    std::lock_guard lock(mu_);
    auto keep = std::stable_partition(pending_.begin(), pending_.end(),
                                      [&](const Pending& p) { return p.job_id != job_id; });
    std::move(keep, pending_.end(), std::back_inserter(dropped));
    pending_.erase(keep, pending_.end());
  }
  for (Pending& p : dropped) Answer(p.ack, "the job was deleted");
  if (auto it = journals_.find(job_id); it != journals_.end()) {
    it->second->CloseFile();
    journals_.erase(it);
  }
  uint64_t bytes = 0;
  const std::string prefix = job_id + ".";
  std::error_code ec;
  std::vector<fs::path> files;
  for (fs::directory_iterator it(checkpoint_dir_, ec), end; !ec && it != end; it.increment(ec))
    if (it->path().filename().string().starts_with(prefix)) files.push_back(it->path());
  for (const fs::path& f : files) {
    std::error_code size_ec, remove_ec;
    const uintmax_t size = fs::file_size(f, size_ec);
    if (fs::remove(f, remove_ec) && !size_ec) bytes += size;
    if (remove_ec)
      spdlog::warn("job {}: {} not removed: {}", job_id, f.filename().string(), remove_ec.message());
  }
  return bytes;
}

void Persister::CloseJournalsBeyondTheCap() {
  size_t open = 0;
  for (const auto& [job, journal] : journals_) open += journal->open();
  if (open <= kMaxOpenJournals) return;
  for (auto& [job, journal] : journals_) journal->CloseFile();
}

}  // namespace pf::server
