//! The threads that run a training's shards: the calling thread runs the first shard, and
//! worker threads that live as long as the training run the others.
//!
//! Long-lived workers keep their memory. A thread started for each step got glibc's arena of
//! the thread before it only when no other thread had taken it meanwhile; otherwise it made a
//! new arena and faulted in another gigabyte of pages (measured: 709k instead of 481k page
//! faults in some 10-epoch runs of `configs/paper.toml`, 938k in some 20-epoch runs, 2-3.5 s
//! each time).

use std::sync::Arc;
use std::sync::mpsc::{Sender, channel};
use std::thread::Scope;

/// A job for a worker: everything it borrows outlives the training (`'env`).
type Job<'env> = Box<dyn FnOnce() + Send + 'env>;

/// The worker threads of one training (none when it runs on one thread).
pub struct Workers<'env> {
    senders: Vec<Sender<Job<'env>>>,
}

impl<'env> Workers<'env> {
    /// Starts `threads - 1` workers in `scope` (each with one libtorch thread); they stop when
    /// the value is dropped.
    pub fn start<'scope>(scope: &'scope Scope<'scope, 'env>, threads: usize) -> Self {
        tch::set_num_threads(1);
        let senders = (1..threads.max(1))
            .map(|_| {
                let (tx, rx) = channel::<Job<'env>>();
                scope.spawn(move || {
                    // A new thread starts with libtorch's default thread count.
                    tch::set_num_threads(1);
                    for job in rx {
                        job();
                    }
                });
                tx
            })
            .collect();
        Workers { senders }
    }

    /// Runs `work` on every shard: the first on the calling thread, shard `k` on worker
    /// `k - 1` (round robin when there are more shards than threads, and all on the calling
    /// thread without workers). Results in shard order.
    pub fn run<T, R>(&self, shards: Vec<T>, work: impl Fn(T) -> R + Send + Sync + 'env) -> Vec<R>
    where
        T: Send + 'env,
        R: Send + 'env,
    {
        if self.senders.is_empty() {
            return shards.into_iter().map(work).collect();
        }
        let work = Arc::new(work);
        let (done, results) = channel();
        let mut shards = shards.into_iter().enumerate();
        let first = shards.next();
        let mut sent = 0;
        for (k, shard) in shards {
            let (work, done) = (Arc::clone(&work), done.clone());
            let job: Job<'env> = Box::new(move || {
                let _ = done.send((k, work(shard)));
            });
            self.senders[(k - 1) % self.senders.len()]
                .send(job)
                .expect("a training worker stopped");
            sent += 1;
        }
        let mut out: Vec<(usize, R)> = first.map(|(k, shard)| (k, work(shard))).into_iter().collect();
        drop(done);
        for _ in 0..sent {
            out.push(results.recv().expect("a training shard panicked"));
        }
        out.sort_by_key(|(k, _)| *k);
        out.into_iter().map(|(_, r)| r).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_come_back_in_shard_order_whatever_the_threads() {
        // Five shards on 1, 2 and 3 threads (round robin beyond the workers); each result names
        // the shard and the thread that ran it.
        let caller = std::thread::current().id();
        for threads in [1, 2, 3] {
            let out: Vec<(u32, bool)> = std::thread::scope(|scope| {
                let workers = Workers::start(scope, threads);
                workers.run((0..5u32).collect(), move |k| {
                    (k * k, std::thread::current().id() == caller)
                })
            });
            assert_eq!(out.iter().map(|r| r.0).collect::<Vec<_>>(), [0, 1, 4, 9, 16]);
            // The first shard always runs on the calling thread; the others only without workers.
            let on_caller: Vec<bool> = out.iter().map(|r| r.1).collect();
            let expected = [true, threads == 1, threads == 1, threads == 1, threads == 1];
            assert_eq!(on_caller, expected, "{threads} threads");
        }
    }
}
