//! A result computed in a background thread and polled by the UI each frame (the
//! compare view's reference, the trade-off view's sweep, the per-plugin ablation).

use std::sync::mpsc;

pub struct Job<T> {
    rx: mpsc::Receiver<Result<T, String>>,
    /// What runs, for the message if the thread dies without an answer.
    what: &'static str,
}

impl<T: Send + 'static> Job<T> {
    /// Runs `f` in a new thread.
    pub fn spawn(
        what: &'static str,
        f: impl FnOnce() -> Result<T, String> + Send + 'static,
    ) -> Self {
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(f());
        });
        Self { rx, what }
    }

    /// The result once the thread has finished; an error if it stopped without one
    /// (a panic).
    pub fn poll(&self) -> Option<Result<T, String>> {
        match self.rx.try_recv() {
            Ok(r) => Some(r),
            Err(mpsc::TryRecvError::Empty) => None,
            Err(mpsc::TryRecvError::Disconnected) => {
                Some(Err(format!("the {} thread stopped", self.what)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wait<T: Send + 'static>(job: &Job<T>) -> Result<T, String> {
        loop {
            if let Some(r) = job.poll() {
                return r;
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
    }

    #[test]
    fn results_errors_and_a_dead_thread() {
        assert_eq!(wait(&Job::spawn("sum", || Ok(2 + 2))), Ok(4));
        assert_eq!(
            wait(&Job::<u8>::spawn("failing", || Err("no".into()))),
            Err("no".to_string())
        );
        let e = wait(&Job::<u8>::spawn("panicking", || panic!("boom"))).unwrap_err();
        assert_eq!(e, "the panicking thread stopped");
    }
}
