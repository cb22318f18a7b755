#include "client/snapshot_buffer.h"

#include <algorithm>
#include <cmath>

namespace edgephys {
namespace {

bool IsFinite(const Vec3f& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Returns false if `q` is non-finite or too short to normalise.
bool NormaliseQuat(Quatf* q) {
  if (!std::isfinite(q->x) || !std::isfinite(q->y) || !std::isfinite(q->z) ||
      !std::isfinite(q->w)) {
    return false;
  }
  const double norm = std::sqrt(double{q->x} * q->x + double{q->y} * q->y + double{q->z} * q->z +
                                double{q->w} * q->w);
  if (norm < 1e-6) return false;
  const float inv = static_cast<float>(1.0 / norm);
  q->x *= inv;
  q->y *= inv;
  q->z *= inv;
  q->w *= inv;
  return true;
}

// Adds `value` to a sliding window of N values held twice: `ring` in arrival order (`*next` is
// the slot of the oldest once full) and `sorted` ascending (its first `*count` entries). Once the
// window is full the oldest value leaves it: its sorted entry becomes a hole that walks to
// `value`'s place, moving only the entries in between.
template <size_t N>
void SlideWindow(double value, std::array<double, N>& ring, std::array<double, N>& sorted,
                 size_t* count, size_t* next) {
  double* a = sorted.data();
  size_t n = *count;
  size_t hole;
  if (n < N) {
    hole = n++;
    *count = n;
  } else {
    // The oldest value is in `sorted` (it went in unchanged): find one entry equal to it.
    hole = static_cast<size_t>(std::lower_bound(a, a + n, ring[*next]) - a);
  }
  while (hole + 1 < n && a[hole + 1] < value) {
    a[hole] = a[hole + 1];
    ++hole;
  }
  while (hole > 0 && a[hole - 1] > value) {
    a[hole] = a[hole - 1];
    --hole;
  }
  a[hole] = value;
  ring[*next] = value;
  *next = *next + 1 == N ? 0 : *next + 1;
}

// `config` with its slew clamped to [0, 0.9], max_delay_s at least min_delay_s and `capacity`.
SnapshotBufferConfig Normalized(SnapshotBufferConfig config, size_t capacity) {
  config.capacity = capacity;
  config.max_slew = std::clamp(config.max_slew, 0.0, 0.9);
  config.max_delay_s = std::max(config.max_delay_s, config.min_delay_s);
  return config;
}

}  // namespace

SnapshotBuffer::SnapshotBuffer(const SnapshotBufferConfig& config)
    : config_(Normalized(config, std::max<size_t>(config.capacity, 2))) {
  ring_.resize(config_.capacity);
  capacity_ = ring_.size();
  Clear();
}

void SnapshotBuffer::Reconfigure(const SnapshotBufferConfig& config) {
  config_ = Normalized(config, capacity_);
  UpdateEstimates();
}

void SnapshotBuffer::Clear() {
  head_ = 0;
  count_ = 0;
  has_offset_ = false;
  bucket_start_s_ = bucket_min_s_ = previous_bucket_min_s_ = 0;
  raw_offsets_count_ = raw_offsets_next_ = 0;
  gaps_count_ = gaps_next_ = 0;
  jitter_p95_s_ = 0;
  playout_started_ = false;
  last_local_now_s_ = render_time_s_ = current_delay_s_ = 0;
  UpdateEstimates();
}

size_t SnapshotBuffer::UpperBound(double sender_time_s) const {
  size_t lo = 0, hi = count_;
  while (lo < hi) {
    const size_t mid = lo + (hi - lo) / 2;
    if ((*this)[mid].sender_time_s <= sender_time_s) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return lo;
}

InsertResult SnapshotBuffer::Insert(const Snapshot& snapshot, double receive_time_s) {
  Snapshot s = snapshot;
  if (!std::isfinite(s.sender_time_s) || !std::isfinite(receive_time_s) || !IsFinite(s.position) ||
      !NormaliseQuat(&s.rotation) || (s.has_linear_velocity && !IsFinite(s.linear_velocity)) ||
      (s.has_angular_velocity && !IsFinite(s.angular_velocity))) {
    return InsertResult::kInvalid;
  }

  // In-order arrivals (the common case) go after the newest without a search; UpperBound would
  // return count_ for them too.
  size_t pos = count_ == 0 || newest().sender_time_s <= s.sender_time_s
                   ? count_
                   : UpperBound(s.sender_time_s);
  if ((pos > 0 && s.sender_time_s - (*this)[pos - 1].sender_time_s < config_.duplicate_epsilon_s) ||
      (pos < count_ &&
       (*this)[pos].sender_time_s - s.sender_time_s < config_.duplicate_epsilon_s)) {
    return InsertResult::kDuplicate;
  }

  const double raw_offset = receive_time_s - s.sender_time_s;
  UpdateOffset(raw_offset, receive_time_s);
  SlideWindow(raw_offset, raw_offsets_, raw_offsets_sorted_, &raw_offsets_count_,
              &raw_offsets_next_);

  if (count_ == capacity_) {
    if (pos == 0) {
      UpdateEstimates();
      return InsertResult::kTooOld;
    }
    head_ = Slot(1);  // evict the oldest
    --count_;
    --pos;
  }
  // Shift [pos, count_) one slot towards the newest end, then place `s` at pos.
  for (size_t i = count_; i > pos; --i) ring_[Slot(i)] = ring_[Slot(i - 1)];
  ring_[Slot(pos)] = s;
  ++count_;

  if (pos == count_ - 1 && count_ >= 2) {
    SlideWindow(s.sender_time_s - (*this)[pos - 1].sender_time_s, gaps_, gaps_sorted_, &gaps_count_,
                &gaps_next_);
  }
  UpdateEstimates();
  return InsertResult::kInserted;
}

void SnapshotBuffer::UpdateOffset(double raw_offset_s, double receive_time_s) {
  if (!has_offset_) {
    has_offset_ = true;
    bucket_start_s_ = receive_time_s;
    bucket_min_s_ = previous_bucket_min_s_ = raw_offset_s;
    return;
  }
  const double elapsed = receive_time_s - bucket_start_s_;
  if (elapsed >= config_.offset_window_s) {
    // A new bucket; the previous one only counts if it ended less than a window ago.
    previous_bucket_min_s_ = elapsed >= 2 * config_.offset_window_s ? raw_offset_s : bucket_min_s_;
    bucket_min_s_ = raw_offset_s;
    bucket_start_s_ = receive_time_s;
  } else {
    bucket_min_s_ = std::min(bucket_min_s_, raw_offset_s);
  }
}

double SnapshotBuffer::clock_offset_s() const {
  return has_offset_ ? std::min(bucket_min_s_, previous_bucket_min_s_) : 0.0;
}

void SnapshotBuffer::UpdateEstimates() {
  // Median: the (n / 2)-th smallest gap, 0-based.
  send_interval_s_ =
      gaps_count_ > 0 ? gaps_sorted_[gaps_count_ / 2] : config_.initial_send_interval_s;

  if (raw_offsets_count_ > 0) {
    // Nearest-rank 95th percentile: ceil(0.95 n)-th smallest.
    const size_t rank = (raw_offsets_count_ * 95 + 99) / 100;
    jitter_p95_s_ = std::max(0.0, raw_offsets_sorted_[rank - 1] - clock_offset_s());
  } else {
    jitter_p95_s_ = 0;
  }

  target_delay_s_ = std::clamp(config_.interval_multiplier * send_interval_s_ + jitter_p95_s_,
                               config_.min_delay_s, config_.max_delay_s);
}

double SnapshotBuffer::RenderTime(double local_now_s) {
  if (!playout_started_) {
    if (count_ == 0) return 0.0;
    playout_started_ = true;
    last_local_now_s_ = local_now_s;
    render_time_s_ = EstimateSenderTime(local_now_s) - target_delay_s_;
    current_delay_s_ = target_delay_s_;
    return render_time_s_;
  }
  const double dt = std::max(0.0, local_now_s - last_local_now_s_);
  last_local_now_s_ = std::max(last_local_now_s_, local_now_s);
  const double sender_now = EstimateSenderTime(last_local_now_s_);
  const double target = sender_now - target_delay_s_;
  const double nominal = render_time_s_ + dt;
  const double error = target - nominal;
  if (error > config_.resync_threshold_s) {
    render_time_s_ = target;  // far behind (stall, long loss): jump forward
  } else {
    const double max_adjust = config_.max_slew * dt;
    render_time_s_ = nominal + std::clamp(error, -max_adjust, max_adjust);
  }
  current_delay_s_ = sender_now - render_time_s_;
  return render_time_s_;
}

}  // namespace edgephys
