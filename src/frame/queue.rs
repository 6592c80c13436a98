//! A channel bounded in bytes, not in messages: what the render of [`super::RenderJob::render_sequence`]
//! hands its writer. Small frames queue several deep, so the render runs ahead of a writer that
//! is slow for a frame or two (a frame's fsync, a busy disk); a frame in strips (each up to
//! 283 MB: the renderer's 256 MiB readback budget at 68 bytes a pixel, 72 here) queues one strip
//! at a time. Either way what waits in the queue stays under [`capacity_for`] the frame size, so
//! memory stays flat however long the sequence.

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex};

/// At most this many bytes of strips wait for the writer (beside the strip being written and
/// the one being rendered). A message larger than this is still sent, alone, once the queue is
/// empty.
pub(super) const WRITE_QUEUE_BYTES: usize = 256 << 20;

/// The queue's capacity for frames of `width` x `height`: two whole frames with every layer
/// (1280x720: 192 MB), at most [`WRITE_QUEUE_BYTES`]. So the frames in flight (one rendered, two
/// waiting, one written) are the four strips the memory estimate counts
/// (`scene::resources`, `BYTES_PER_STRIP_PIXEL`), for small frames as for large.
pub(super) fn capacity_for(width: u32, height: u32) -> usize {
    let frame =
        width as usize * height as usize * crate::draw::RenderedFrame::LAYER_BYTES_PER_PIXEL;
    frame.saturating_mul(2).min(WRITE_QUEUE_BYTES)
}

struct State<T> {
    queue: VecDeque<(T, usize)>,
    bytes: usize,
    /// The most bytes that ever waited at once.
    peak: usize,
    senders: bool,
    receiver: bool,
}

struct Shared<T> {
    state: Mutex<State<T>>,
    changed: Condvar,
    capacity: usize,
}

pub(super) struct ByteSender<T>(Arc<Shared<T>>);
pub(super) struct ByteReceiver<T>(Arc<Shared<T>>);

/// A channel that holds at most `capacity` bytes of messages (or one message of any size).
pub(super) fn byte_channel<T>(capacity: usize) -> (ByteSender<T>, ByteReceiver<T>) {
    let shared = Arc::new(Shared {
        state: Mutex::new(State {
            queue: VecDeque::new(),
            bytes: 0,
            peak: 0,
            senders: true,
            receiver: true,
        }),
        changed: Condvar::new(),
        capacity,
    });
    (ByteSender(shared.clone()), ByteReceiver(shared))
}

fn lock<T>(shared: &Shared<T>) -> std::sync::MutexGuard<'_, State<T>> {
    // A panic while holding the lock leaves the queue consistent (every change is one statement).
    shared
        .state
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl<T> ByteSender<T> {
    /// Queues `message`, of `bytes` bytes, once there is room for it (at once when the queue is
    /// empty). Gives the message back if the receiver is gone.
    pub fn send(&self, message: T, bytes: usize) -> Result<(), T> {
        let shared = &*self.0;
        let mut state = lock(shared);
        while state.receiver && state.bytes > 0 && state.bytes + bytes > shared.capacity {
            state = shared
                .changed
                .wait(state)
                .unwrap_or_else(|p| p.into_inner());
        }
        if !state.receiver {
            return Err(message);
        }
        state.bytes += bytes;
        state.peak = state.peak.max(state.bytes);
        state.queue.push_back((message, bytes));
        shared.changed.notify_all();
        Ok(())
    }
}

impl<T> Drop for ByteSender<T> {
    fn drop(&mut self) {
        lock(&self.0).senders = false;
        self.0.changed.notify_all();
    }
}

impl<T> ByteReceiver<T> {
    /// The next message, waiting for one; `None` once the sender is gone and the queue empty.
    pub fn recv(&self) -> Option<T> {
        let shared = &*self.0;
        let mut state = lock(shared);
        loop {
            if let Some((message, bytes)) = state.queue.pop_front() {
                state.bytes -= bytes;
                shared.changed.notify_all();
                return Some(message);
            }
            if !state.senders {
                return None;
            }
            state = shared
                .changed
                .wait(state)
                .unwrap_or_else(|p| p.into_inner());
        }
    }

    /// The most bytes that waited in the queue at once so far.
    pub fn peak_bytes(&self) -> usize {
        lock(&self.0).peak
    }
}

impl<T> Drop for ByteReceiver<T> {
    fn drop(&mut self) {
        let mut state = lock(&self.0);
        state.receiver = false;
        // What waits is dropped now: nobody will write it.
        state.queue.clear();
        state.bytes = 0;
        drop(state);
        self.0.changed.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn what_waits_stays_under_the_capacity_and_arrives_in_order() {
        let (sender, receiver) = byte_channel::<(u32, usize)>(1000);
        let sizes: Vec<usize> = (0..200).map(|i| [100, 300, 700, 50, 999][i % 5]).collect();
        let expected = sizes.clone();
        let producer = std::thread::spawn(move || {
            for (i, &size) in sizes.iter().enumerate() {
                sender.send((i as u32, size), size).unwrap();
            }
        });
        let mut got = Vec::new();
        while let Some((i, size)) = receiver.recv() {
            assert_eq!(i as usize, got.len());
            got.push(size);
            if i % 7 == 0 {
                // A slow writer: the producer fills the queue meanwhile.
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        producer.join().unwrap();
        assert_eq!(got, expected);
        let peak = receiver.peak_bytes();
        assert!(peak <= 1000, "{peak} bytes waited");
        assert!(
            peak > 700,
            "the queue held more than one message at once ({peak})"
        );
    }

    #[test]
    fn the_capacity_is_two_frames_up_to_the_limit() {
        let pixels = 1280 * 720;
        let frame = crate::draw::RenderedFrame {
            width: 1280,
            height: 720,
            beauty_rgba: vec![[0.0; 4]; pixels],
            depth_m: vec![0.0; pixels],
            apparent_depth_m: vec![0.0; pixels],
            position: vec![[0.0; 3]; pixels],
            flags: vec![0; pixels],
            object: vec![0; pixels],
            water_matte: vec![0.0; pixels],
            water_reflection: vec![[0.0; 4]; pixels],
            motion_px: vec![[0.0; 2]; pixels],
            coverage: vec![Default::default(); pixels],
        };
        assert_eq!(frame.layer_bytes(), 104 * pixels);
        assert_eq!(capacity_for(1280, 720), 2 * frame.layer_bytes());
        assert_eq!(capacity_for(7680, 4320), WRITE_QUEUE_BYTES);
    }

    #[test]
    fn a_message_larger_than_the_capacity_goes_alone() {
        let (sender, receiver) = byte_channel::<usize>(100);
        sender.send(1, 500).unwrap();
        let blocked = std::thread::spawn(move || {
            sender.send(2, 10).unwrap();
            sender
        });
        std::thread::sleep(Duration::from_millis(50));
        assert!(
            !blocked.is_finished(),
            "nothing joins a message past the capacity"
        );
        assert_eq!(receiver.recv(), Some(1));
        let sender = blocked.join().unwrap();
        assert_eq!(receiver.recv(), Some(2));
        drop(sender);
        assert_eq!(receiver.recv(), None);
        assert_eq!(receiver.peak_bytes(), 500);
    }

    #[test]
    fn a_sender_waiting_for_room_is_released_when_the_receiver_goes() {
        let (sender, receiver) = byte_channel::<usize>(100);
        sender.send(1, 80).unwrap();
        let waiting = std::thread::spawn(move || sender.send(2, 80));
        std::thread::sleep(Duration::from_millis(50));
        drop(receiver);
        assert_eq!(waiting.join().unwrap(), Err(2));
    }
}
