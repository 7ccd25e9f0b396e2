//! Stage 1b, the package: a bake's tiles dealt to its threads one at a time, each thread taking the next
//! as it comes free.
//!
//! A tile's cost follows the terrain: a tile of flat sea codes and decodes several times faster than one
//! of mountains, so a row shared in runs of adjacent tiles (the sea one side, the land the other) left a
//! core idle for much of the row. Taken one at a time, the threads finish together whatever the terrain.
//! Each item's result goes to its own slot, so nothing made depends on which thread made it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, PoisonError};

/// Runs `f(worker, index, item)` over every item of `items`, one scoped thread per worker of `workers`
/// taking the items in order as it comes free, while `beside` runs on this thread; returns the error of
/// the first failing item in item order (the one a single thread going through them in turn would meet:
/// once an item fails no thread takes another, and every item before it was taken earlier and is
/// finished), and what `beside` returned. With one worker or one item, all of it runs on this thread.
/// `what` names the threads in the panic of a broken invariant.
pub(crate) fn deal<T: Send, W: Send, E: Send, B>(
    items: &mut [T],
    workers: &mut [W],
    f: impl Fn(&mut W, usize, &mut T) -> Result<(), E> + Sync,
    beside: impl FnOnce() -> B,
    what: &str,
) -> (Result<(), E>, B) {
    if workers.len() <= 1 || items.len() <= 1 {
        let b = beside();
        let Some(w) = workers.first_mut() else {
            assert!(items.is_empty(), "items to deal need a worker");
            return (Ok(()), b);
        };
        let r = items
            .iter_mut()
            .enumerate()
            .try_for_each(|(i, item)| f(w, i, item));
        return (r, b);
    }
    let n = workers.len().min(items.len());
    let next = Mutex::new(items.iter_mut().enumerate());
    let failed = AtomicBool::new(false);
    let run = |w: &mut W| -> Option<(usize, E)> {
        while !failed.load(Ordering::Relaxed) {
            // The lock is held only to take the item.
            let taken = next.lock().unwrap_or_else(PoisonError::into_inner).next();
            let (i, item) = taken?;
            if let Err(e) = f(w, i, item) {
                failed.store(true, Ordering::Relaxed);
                return Some((i, e));
            }
        }
        None
    };
    let run = &run;
    std::thread::scope(|s| {
        let handles: Vec<_> = workers[..n]
            .iter_mut()
            .map(|w| s.spawn(move || run(w)))
            .collect();
        let b = beside();
        let first = handles
            .into_iter()
            .filter_map(|h| h.join().unwrap_or_else(|_| panic!("{what}")))
            .min_by_key(|(i, _)| *i);
        (first.map_or(Ok(()), |(_, e)| Err(e)), b)
    })
}

#[cfg(test)]
mod tests {
    use super::deal;

    #[test]
    fn every_item_once_and_the_first_error_in_order() {
        for workers in 1..4 {
            let mut items: Vec<u32> = (0..100).collect();
            let mut ws = vec![0u32; workers];
            let (r, b) = deal(
                &mut items,
                &mut ws,
                |w, i, item| {
                    *w += 1;
                    *item = *item * 2 + u32::try_from(i).expect("small");
                    Ok::<(), u32>(())
                },
                || 7,
                "test",
            );
            assert_eq!((r, b), (Ok(()), 7));
            assert_eq!(ws.iter().sum::<u32>(), 100);
            assert!(items.iter().zip(0u32..).all(|(&v, i)| v == 3 * i));
            let mut items: Vec<u32> = (0..100).collect();
            let (r, ()) = deal(
                &mut items,
                &mut ws,
                |_, i, _| if i % 10 == 3 { Err(i) } else { Ok(()) },
                || (),
                "test",
            );
            assert_eq!(r, Err(3));
        }
    }
}
