//! A queue that a real-time thread drains without ever waiting for its senders.
//!
//! # Why
//! `std::sync::mpsc` (like crossbeam's channels) makes a receiver spin, yielding, while a
//! sender is half-way through writing a message. When the sender is a web thread at nice +10
//! preempted in that window and the receiver is a `SCHED_FIFO` thread, the receiver's
//! `sched_yield` gives the CPU to nobody who can finish the write: the juggler's supervisor
//! was measured spinning 13.9 ms in `try_recv` under web load, past its 9 ms lease. A
//! [`MailboxReceiver`] only ever *tries* the queue's lock: when a sender holds it, the
//! messages are taken at the next pass instead.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError, TryLockError};

#[derive(Debug)]
struct Inner<T> {
    queue: Mutex<VecDeque<T>>,
    receiver_alive: AtomicBool,
}

/// The sending side of a [`mailbox`]; cloned for each sender.
#[derive(Debug)]
pub struct MailboxSender<T> {
    inner: Arc<Inner<T>>,
}

impl<T> Clone for MailboxSender<T> {
    fn clone(&self) -> Self {
        Self { inner: Arc::clone(&self.inner) }
    }
}

/// The receiving side of a [`mailbox`] (one per mailbox).
#[derive(Debug)]
pub struct MailboxReceiver<T> {
    inner: Arc<Inner<T>>,
}

/// A new mailbox: any number of senders, one receiver that never waits.
pub fn mailbox<T>() -> (MailboxSender<T>, MailboxReceiver<T>) {
    let inner = Arc::new(Inner { queue: Mutex::new(VecDeque::new()), receiver_alive: AtomicBool::new(true) });
    (MailboxSender { inner: Arc::clone(&inner) }, MailboxReceiver { inner })
}

impl<T> MailboxSender<T> {
    /// Queues `message` for the receiver (waits only for other senders and for the
    /// receiver's taking of the queue, which is a swap).
    ///
    /// # Errors
    /// The receiver is gone: the message, undelivered.
    pub fn send(&self, message: T) -> Result<(), T> {
        if !self.inner.receiver_alive.load(Ordering::Acquire) {
            return Err(message);
        }
        self.inner.queue.lock().unwrap_or_else(PoisonError::into_inner).push_back(message);
        Ok(())
    }
}

impl<T> MailboxReceiver<T> {
    /// The messages queued so far, oldest first; empty when there are none or when a sender
    /// holds the queue right now (they are taken at the next call). Never waits.
    pub fn try_take(&self) -> VecDeque<T> {
        let mut queue = match self.inner.queue.try_lock() {
            Ok(q) => q,
            Err(TryLockError::Poisoned(p)) => p.into_inner(),
            Err(TryLockError::WouldBlock) => return VecDeque::new(),
        };
        if queue.is_empty() {
            return VecDeque::new();
        }
        std::mem::take(&mut *queue)
    }
}

impl<T> Drop for MailboxReceiver<T> {
    fn drop(&mut self) {
        self.inner.receiver_alive.store(false, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn messages_arrive_in_order_and_a_busy_queue_is_left_for_the_next_pass() {
        let (tx, rx) = mailbox();
        tx.send(1).unwrap();
        tx.clone().send(2).unwrap();
        {
            // A sender holding the queue (preempted mid-send): the receiver does not wait.
            let _held = tx.inner.queue.lock().unwrap();
            assert!(rx.try_take().is_empty());
        }
        assert_eq!(Vec::from(rx.try_take()), vec![1, 2]);
        assert!(rx.try_take().is_empty());
        drop(rx);
        assert_eq!(tx.send(3), Err(3), "the receiver is gone");
    }
}
