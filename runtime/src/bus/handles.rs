//! One iceoryx2 service handle per service and process.
//!
//! Opening an iceoryx2 service (`open_or_create`) maps its dynamic config segment and keeps
//! its static config file open: two descriptors and a mapping per handle. Ports made from one
//! handle share them. robotd opens the same services many times in one process (every actor's
//! subscriber on `arm/state`, every client's wake-up events), so the bus keeps the handles it
//! opened and hands out the same one again while any port still uses it. The cache holds them
//! weakly: when the last port of a service is dropped, its handle closes as before (per-client
//! reply topics come and go with their clients).

use super::BusError;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, Weak};

/// Open service handles of one kind, by a key that names the service and its settings.
pub(crate) struct Handles<F> {
    open: Mutex<HashMap<String, Weak<F>>>,
}

impl<F> Default for Handles<F> {
    fn default() -> Self {
        Self {
            open: Mutex::new(HashMap::new()),
        }
    }
}

impl<F> Handles<F> {
    /// The handle under `key` if a port still holds it, else the one `open` makes (kept for
    /// later callers while it is in use).
    pub(crate) fn get_or_open(
        &self,
        key: &str,
        open: impl FnOnce() -> Result<F, BusError>,
    ) -> Result<Arc<F>, BusError> {
        let mut handles = self.open.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(handle) = handles.get(key).and_then(Weak::upgrade) {
            return Ok(handle);
        }
        // Forget handles nobody holds any more (opens are rare: setup, a new client).
        handles.retain(|_, handle| handle.strong_count() > 0);
        let handle = Arc::new(open()?);
        handles.insert(key.to_owned(), Arc::downgrade(&handle));
        Ok(handle)
    }

    /// Handles currently held by some port.
    #[cfg(test)]
    pub(crate) fn held(&self) -> usize {
        let handles = self.open.lock().unwrap_or_else(|e| e.into_inner());
        handles.values().filter(|h| h.strong_count() > 0).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_handle_is_shared_while_held_and_reopened_after() {
        let handles: Handles<u32> = Handles::default();
        let mut opened = 0;
        let mut open = || {
            opened += 1;
            Ok(opened)
        };
        let first = handles.get_or_open("a", &mut open).unwrap();
        let again = handles.get_or_open("a", &mut open).unwrap();
        assert!(Arc::ptr_eq(&first, &again));
        let other = handles.get_or_open("b", &mut open).unwrap();
        assert_eq!((*first, *other), (1, 2));
        assert_eq!(handles.held(), 2);
        drop((first, again));
        assert_eq!(handles.held(), 1);
        let reopened = handles.get_or_open("a", &mut open).unwrap();
        assert_eq!(*reopened, 3, "a dropped handle is opened anew");
    }

    #[test]
    fn a_failed_open_is_not_kept() {
        let handles: Handles<u32> = Handles::default();
        let failed = handles.get_or_open("a", || {
            Err(BusError::Setup {
                what: "x".into(),
                reason: "y".into(),
            })
        });
        assert!(failed.is_err());
        assert_eq!(*handles.get_or_open("a", || Ok(7)).unwrap(), 7);
    }
}
