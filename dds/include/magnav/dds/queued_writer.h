// A writer that publishes from a thread of its own, with flow control.
//
// Why: a service answers samples inside a reader's callback, i.e. on a Fast
// DDS receive thread. When it produces a burst — a restarted tracker
// rebuilding its tracks from the sensor stream's history (1000 samples per
// sensor) publishes hundreds of estimates of one track at once — a KEEP_LAST
// writer (estimates: 10 per key) overwrites estimates its readers have not
// received yet: they are lost (measured: `magnav record` lost 10 of 685 after
// a tracker restart, and in some runs most of the burst). Flow control
// (Writer::SetFlowControl: wait for the readers' acknowledgments every few
// samples) stops that, but must not run on the receive thread: the
// acknowledgment may have to come in through that very thread. So Write()
// only queues, and the thread writes with flow control.
//
// Order is kept (unregistrations too). The queue is bounded (max_queued): past it the oldest
// queued message is dropped and counted (dropped()); a reader that does not
// acknowledge within the flow-control timeout (slow, or dead and not yet
// forgotten) delays the queue by that much, is logged and counted in
// stats().flow_timeouts, and the queue goes on. Thread-safe.
#pragma once

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>

#include "magnav/dds/node.h"

namespace magnav::dds {

template <class M>
class QueuedWriter {
 public:
  // window: acknowledgments are awaited after every `window` samples (keep it
  // below the writer's history depth); timeout: how long at most.
  QueuedWriter(std::unique_ptr<Writer<M>> writer, int window, std::chrono::milliseconds timeout,
               std::size_t max_queued = 100000)
      : writer_(std::move(writer)), max_queued_(max_queued) {
    writer_->SetFlowControl(window, timeout);
    thread_ = std::thread([this] { Run(); });
  }
  // Writes what is still queued (the flow control's timeouts bound it), then
  // stops.
  ~QueuedWriter() {
    {
      std::lock_guard<std::mutex> lk(mu_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  QueuedWriter(const QueuedWriter&) = delete;
  QueuedWriter& operator=(const QueuedWriter&) = delete;

  // Queues a message; returns at once.
  void Write(const M& m) { Push({m, false}); }
  // Queues the end of m's key (Writer::Unregister), after what is queued.
  void Unregister(const M& m) { Push({m, true}); }
  // Waits until the queue is written and every matched reader acknowledged
  // it; false on timeout.
  bool WaitForAcknowledgments(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    {
      std::unique_lock<std::mutex> lk(mu_);
      if (!idle_cv_.wait_until(lk, deadline, [&] { return queue_.empty() && !writing_; })) return false;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    return writer_->WaitForAcknowledgments(std::max(left, std::chrono::milliseconds(0)));
  }
  // Messages queued so far (writes and unregistrations, dropped ones included).
  std::uint64_t pushed() const {
    std::lock_guard<std::mutex> lk(mu_);
    return pushed_;
  }
  // Waits until the first `count` messages queued have been handed to the
  // middleware (or dropped) and every matched reader acknowledged what was
  // written by then; newer messages may still be queued. False on timeout.
  bool WaitForDelivered(std::uint64_t count, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    {
      std::unique_lock<std::mutex> lk(mu_);
      if (!idle_cv_.wait_until(lk, deadline, [&] { return done_ >= count; })) return false;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    return writer_->WaitForAcknowledgments(std::max(left, std::chrono::milliseconds(0)));
  }
  const EndpointStats& stats() const { return writer_->stats(); }
  std::uint64_t dropped() const {
    std::lock_guard<std::mutex> lk(mu_);
    return dropped_;
  }
  // Writes or unregistrations the middleware refused.
  std::uint64_t refused() const {
    std::lock_guard<std::mutex> lk(mu_);
    return refused_;
  }
  std::size_t queued() const {
    std::lock_guard<std::mutex> lk(mu_);
    return queue_.size();
  }

 private:
  struct Op {
    M message;
    bool unregister;
  };
  void Push(Op op) {
    {
      std::lock_guard<std::mutex> lk(mu_);
      if (queue_.size() >= max_queued_) {
        queue_.pop_front();
        ++dropped_;
        ++done_;
      }
      queue_.push_back(std::move(op));
      ++pushed_;
    }
    cv_.notify_all();
  }

  void Run() {
    std::unique_lock<std::mutex> lk(mu_);
    while (true) {
      cv_.wait(lk, [&] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) break;  // stop_ and nothing left
      Op op = std::move(queue_.front());
      queue_.pop_front();
      writing_ = true;
      lk.unlock();
      // The flow control may wait here, never on a receive thread.
      const bool ok = op.unregister ? writer_->Unregister(op.message) : writer_->Write(op.message);
      lk.lock();
      if (!ok) ++refused_;
      writing_ = false;
      ++done_;
      idle_cv_.notify_all();
    }
    idle_cv_.notify_all();
  }

  std::unique_ptr<Writer<M>> writer_;
  std::size_t max_queued_;
  mutable std::mutex mu_;
  std::condition_variable cv_, idle_cv_;
  std::deque<Op> queue_;
  bool stop_ = false, writing_ = false;
  std::uint64_t dropped_ = 0, refused_ = 0;
  std::uint64_t pushed_ = 0, done_ = 0;  // queued so far; written, refused or dropped so far
  std::thread thread_;
};

}  // namespace magnav::dds
