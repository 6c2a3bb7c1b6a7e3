// Linked into every executable of a MAGNAV_TSAN build (CMakeLists.txt), nowhere else.
//
// Debian's libfastrtps 2.9 locks its timed mutexes with pthread_mutex_clocklock
// (glibc 2.30+, what libstdc++'s std::timed_mutex::try_lock_until uses for
// steady_clock), and the ThreadSanitizer runtimes of GCC 12 and clang 14 do not
// intercept that function. TSan then never sees those locks: it reports
// "unlock of an unlocked mutex" at every unlock, and, worse, misses the order
// the critical sections give, so it would report races that are none. This
// definition, found before glibc's by the dynamic linker (the executable comes
// first), re-expresses the lock with pthread_mutex_timedlock, which TSan does
// intercept. The only difference: the deadline is converted from `clock` to
// CLOCK_REALTIME once, so a wall-clock step during the wait moves it (harmless
// in a test run).
#include <pthread.h>

#include <cerrno>
#include <ctime>

namespace {
constexpr long kNanosPerSecond = 1000000000L;
}  // namespace

extern "C" int pthread_mutex_clocklock(pthread_mutex_t* mutex, clockid_t clock, const struct timespec* abstime) {
  if (clock == CLOCK_REALTIME) return pthread_mutex_timedlock(mutex, abstime);
  if (clock != CLOCK_MONOTONIC) return EINVAL;
  timespec mono_now{}, real_now{};
  clock_gettime(CLOCK_MONOTONIC, &mono_now);
  clock_gettime(CLOCK_REALTIME, &real_now);
  // Deadline on the realtime clock: now (realtime) + (abstime - now (monotonic)), in ns.
  long long ns = (static_cast<long long>(abstime->tv_sec) - mono_now.tv_sec) * kNanosPerSecond +
                 (abstime->tv_nsec - mono_now.tv_nsec) + static_cast<long long>(real_now.tv_sec) * kNanosPerSecond +
                 real_now.tv_nsec;
  if (ns < 0) ns = 0;
  const timespec deadline{static_cast<time_t>(ns / kNanosPerSecond), static_cast<long>(ns % kNanosPerSecond)};
  return pthread_mutex_timedlock(mutex, &deadline);
}
