//! Reservations of a station by time slot, and the cleanup due when a slot ends.
//!
//! Slots are half-open `[start, end)`: one may start exactly when another ends. Slots of one
//! station never overlap (checked atomically by the store). When a slot ends — on time,
//! cancelled early by its holder, or ended by an admin — [`Reservations::due_cleanups`]
//! lists what the station must do before anyone but an admin commands it again: bring the
//! machine to a safe, homed state and delete the holder's programs and traces that were not
//! exported. The station executes the actions and reports with
//! [`Reservations::complete_cleanup`].

use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::authz::{decide, Action, Actor, Denied, Facts, StudentLimits};
use crate::program::ProgramKind;
use crate::role::Role;
use crate::store::{BookOutcome, ReservationFilter, Store, StoreError};
use crate::time::UnixMs;

/// Booking rules (admins are exempt from all but the overlap rule).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReservationPolicy {
    /// Longest slot (default 2 h).
    pub max_slot_secs: u64,
    /// Shortest slot (default 5 min).
    pub min_slot_secs: u64,
    /// How far ahead a slot may start (default 14 days).
    pub horizon_secs: u64,
    /// How far in the past a slot may start (clock skew of the browser; default 5 min).
    pub start_grace_secs: u64,
    /// Most slots a student may hold that have not ended yet (default 3).
    pub max_upcoming_per_user: usize,
}

impl Default for ReservationPolicy {
    fn default() -> Self {
        ReservationPolicy {
            max_slot_secs: 2 * 3600,
            min_slot_secs: 5 * 60,
            horizon_secs: 14 * 24 * 3600,
            start_grace_secs: 5 * 60,
            max_upcoming_per_user: 3,
        }
    }
}

/// A reservation to be stored.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct NewReservation {
    /// Station.
    pub station: String,
    /// Holder.
    pub user: String,
    /// Start (inclusive).
    pub start: UnixMs,
    /// End (exclusive).
    pub end: UnixMs,
    /// When it was booked.
    pub created: UnixMs,
}

/// A stored reservation.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Reservation {
    /// Id.
    pub id: i64,
    /// Station.
    pub station: String,
    /// Holder.
    pub user: String,
    /// Start (inclusive).
    pub start: UnixMs,
    /// End (exclusive); moved earlier when ended early.
    pub end: UnixMs,
    /// When it was booked.
    pub created: UnixMs,
    /// Who ended it early (the holder cancelling a running slot, or an admin).
    pub ended_by: Option<String>,
    /// The end-of-slot cleanup has been completed.
    pub cleaned: bool,
}

impl Reservation {
    /// True if the slot runs at `now`.
    #[must_use]
    pub fn is_active_at(&self, now: UnixMs) -> bool {
        self.start <= now && now < self.end
    }
}

/// Why a booking or cancellation was refused.
#[derive(Debug, thiserror::Error)]
pub enum ReservationError {
    /// Not allowed for this actor.
    #[error(transparent)]
    Denied(#[from] Denied),
    /// `start >= end`.
    #[error("slot end must be after its start")]
    EmptySlot,
    /// Shorter than the policy's minimum.
    #[error("slot of {} s is shorter than the minimum {} s", length.as_secs(), min.as_secs())]
    TooShort {
        /// Asked.
        length: Duration,
        /// Allowed.
        min: Duration,
    },
    /// Longer than the policy's maximum.
    #[error("slot of {} s is longer than the maximum {} s", length.as_secs(), max.as_secs())]
    TooLong {
        /// Asked.
        length: Duration,
        /// Allowed.
        max: Duration,
    },
    /// Starts in the past.
    #[error("slot starts in the past")]
    InPast,
    /// Starts after the booking horizon.
    #[error("slot starts more than {} s ahead", horizon.as_secs())]
    BeyondHorizon {
        /// Allowed.
        horizon: Duration,
    },
    /// The student already holds the maximum number of upcoming slots.
    #[error("already {held} upcoming reservations (at most {max})")]
    TooMany {
        /// Held.
        held: usize,
        /// Allowed.
        max: usize,
    },
    /// The target user does not exist.
    #[error("no user {0:?}")]
    UnknownUser(String),
    /// The target user is a viewer (viewers cannot command, so cannot hold a slot).
    #[error("user {0:?} is a viewer and cannot hold a slot")]
    ViewerCannotHold(String),
    /// The slot overlaps an existing one.
    #[error("overlaps reservation {} of {} ({}..{})", .0.id, .0.user, .0.start, .0.end)]
    Overlap(Box<Reservation>),
    /// No such reservation.
    #[error("no reservation {0}")]
    NotFound(i64),
    /// The slot is over (nothing to cancel).
    #[error("reservation {0} has already ended")]
    AlreadyEnded(i64),
    /// No slot runs on this station now.
    #[error("no slot is running on {0}")]
    NoActiveSlot(String),
    /// Storage failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// One thing the station must do at the end of a slot, in list order.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum CleanupAction {
    /// Stop motion, bring the machine to a safe state and home every axis.
    MakeSafeAndHome {
        /// Station.
        station: String,
    },
    /// Delete a program or trace file that was not exported.
    DeleteFile {
        /// Station.
        station: String,
        /// Owner.
        owner: String,
        /// Program or trace.
        kind: ProgramKind,
        /// File name.
        name: String,
    },
}

/// The cleanup due for one ended slot.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Cleanup {
    /// The ended reservation.
    pub reservation: Reservation,
    /// What to do: first `MakeSafeAndHome`, then the deletions.
    pub actions: Vec<CleanupAction>,
}

/// Reservations over a [`Store`].
pub struct Reservations {
    store: Arc<dyn Store>,
    policy: ReservationPolicy,
}

impl Reservations {
    /// Reservations in `store` under `policy`.
    #[must_use]
    pub fn new(store: Arc<dyn Store>, policy: ReservationPolicy) -> Self {
        Reservations { store, policy }
    }

    /// The policy in force.
    #[must_use]
    pub fn policy(&self) -> &ReservationPolicy {
        &self.policy
    }

    /// Books `[start, end)` of `station` for `for_user` on behalf of `actor`.
    /// Students book for themselves within the policy; admins for anyone, exempt from the
    /// length, horizon and count rules. Overlaps are refused for everyone.
    ///
    /// # Errors
    /// A [`ReservationError`] naming the rule broken, or a storage failure.
    pub fn book(
        &self,
        actor: &Actor,
        station: &str,
        for_user: &str,
        start: UnixMs,
        end: UnixMs,
        now: UnixMs,
    ) -> Result<Reservation, ReservationError> {
        let action = Action::Reserve { station: station.to_string(), for_user: for_user.to_string() };
        decide(actor, &action, Facts::default(), &StudentLimits::default())?;
        match self.store.get_user(for_user)? {
            None => return Err(ReservationError::UnknownUser(for_user.to_string())),
            Some(u) if u.role == Role::Viewer => {
                return Err(ReservationError::ViewerCannotHold(for_user.to_string()))
            }
            Some(_) => {}
        }
        if start >= end {
            return Err(ReservationError::EmptySlot);
        }
        if actor.role < Role::Admin {
            let p = &self.policy;
            let length = end.since(start);
            let (min, max) = (Duration::from_secs(p.min_slot_secs), Duration::from_secs(p.max_slot_secs));
            if length < min {
                return Err(ReservationError::TooShort { length, min });
            }
            if length > max {
                return Err(ReservationError::TooLong { length, max });
            }
            if start < now.minus(Duration::from_secs(p.start_grace_secs)) {
                return Err(ReservationError::InPast);
            }
            let horizon = Duration::from_secs(p.horizon_secs);
            if start > now.plus(horizon) {
                return Err(ReservationError::BeyondHorizon { horizon });
            }
            let held = self
                .store
                .list_reservations(&ReservationFilter {
                    user: Some(for_user.to_string()),
                    window: Some((now, UnixMs(i64::MAX))),
                    ..ReservationFilter::default()
                })?
                .len();
            if held >= p.max_upcoming_per_user {
                return Err(ReservationError::TooMany { held, max: p.max_upcoming_per_user });
            }
        }
        let new = NewReservation {
            station: station.to_string(),
            user: for_user.to_string(),
            start,
            end,
            created: now,
        };
        match self.store.insert_reservation_if_free(&new)? {
            BookOutcome::Booked(id) => {
                tracing::info!(id, station, user = for_user, start = start.0, end = end.0, "slot booked");
                Ok(Reservation {
                    id,
                    station: new.station,
                    user: new.user,
                    start,
                    end,
                    created: now,
                    ended_by: None,
                    cleaned: false,
                })
            }
            BookOutcome::Overlaps(other) => Err(ReservationError::Overlap(Box::new(other))),
        }
    }

    /// Cancels reservation `id` (its holder, or an admin). A slot not yet started is deleted
    /// (returns `None`); a running slot is ended now (returns the updated reservation, whose
    /// cleanup then becomes due).
    ///
    /// # Errors
    /// [`ReservationError::NotFound`], [`ReservationError::Denied`] (someone else's),
    /// [`ReservationError::AlreadyEnded`], or a storage failure.
    pub fn cancel(
        &self,
        actor: &Actor,
        id: i64,
        now: UnixMs,
    ) -> Result<Option<Reservation>, ReservationError> {
        let r = self.store.get_reservation(id)?.ok_or(ReservationError::NotFound(id))?;
        let action = Action::CancelReservation { station: r.station.clone(), owner: r.user.clone() };
        decide(actor, &action, Facts::default(), &StudentLimits::default())?;
        if r.end <= now {
            return Err(ReservationError::AlreadyEnded(id));
        }
        if r.start > now {
            self.store.delete_reservation(id)?;
            tracing::info!(id, by = %actor.name, "reservation cancelled");
            return Ok(None);
        }
        Ok(Some(self.end_early(r, &actor.name, now)?))
    }

    fn end_early(&self, mut r: Reservation, by: &str, now: UnixMs) -> Result<Reservation, ReservationError> {
        r.end = now;
        r.ended_by = Some(by.to_string());
        self.store.update_reservation(&r)?;
        tracing::info!(id = r.id, station = %r.station, user = %r.user, by, "slot ended early");
        Ok(r)
    }

    /// An admin ends the slot running on `station` now (its cleanup becomes due).
    ///
    /// # Errors
    /// [`ReservationError::Denied`] unless admin, [`ReservationError::NoActiveSlot`], or a
    /// storage failure.
    pub fn end_current(
        &self,
        actor: &Actor,
        station: &str,
        now: UnixMs,
    ) -> Result<Reservation, ReservationError> {
        let r = self
            .active_at(station, now)?
            .ok_or_else(|| ReservationError::NoActiveSlot(station.to_string()))?;
        decide(
            actor,
            &Action::EndSession { user: r.user.clone() },
            Facts::default(),
            &StudentLimits::default(),
        )?;
        self.end_early(r, &actor.name, now)
    }

    /// The reservation running on `station` at `now`.
    ///
    /// # Errors
    /// A storage failure.
    pub fn active_at(&self, station: &str, now: UnixMs) -> Result<Option<Reservation>, ReservationError> {
        Ok(self
            .store
            .list_reservations(&ReservationFilter {
                station: Some(station.to_string()),
                window: Some((now, now.plus(Duration::from_millis(1)))),
                ..ReservationFilter::default()
            })?
            .into_iter()
            .next())
    }

    /// Who holds `station` at `now`.
    ///
    /// # Errors
    /// A storage failure.
    pub fn holder_at(&self, station: &str, now: UnixMs) -> Result<Option<String>, ReservationError> {
        Ok(self.active_at(station, now)?.map(|r| r.user))
    }

    /// A reservation by id.
    ///
    /// # Errors
    /// A storage failure.
    pub fn get(&self, id: i64) -> Result<Option<Reservation>, ReservationError> {
        Ok(self.store.get_reservation(id)?)
    }

    /// Reservations passing `filter`, by start.
    ///
    /// # Errors
    /// A storage failure.
    pub fn list(&self, filter: &ReservationFilter) -> Result<Vec<Reservation>, ReservationError> {
        Ok(self.store.list_reservations(filter)?)
    }

    /// The cleanups due at `now`: one per slot that has ended and is not cleaned, oldest
    /// first. Each lists `MakeSafeAndHome` first, then a `DeleteFile` for every program
    /// and trace of the holder on that station that is not exported.
    ///
    /// # Errors
    /// A storage failure.
    pub fn due_cleanups(&self, now: UnixMs) -> Result<Vec<Cleanup>, ReservationError> {
        let ended = self.store.list_reservations(&ReservationFilter {
            pending_cleanup_at: Some(now),
            ..ReservationFilter::default()
        })?;
        let mut out = Vec::with_capacity(ended.len());
        for r in ended {
            let mut actions = vec![CleanupAction::MakeSafeAndHome { station: r.station.clone() }];
            for p in self.store.list_programs(Some(&r.station), Some(&r.user))? {
                if !p.exported {
                    actions.push(CleanupAction::DeleteFile {
                        station: p.station,
                        owner: p.owner,
                        kind: p.kind,
                        name: p.name,
                    });
                }
            }
            out.push(Cleanup { reservation: r, actions });
        }
        Ok(out)
    }

    /// Records that the station executed `cleanup`: removes the metadata of the deleted
    /// files and marks the reservation cleaned (commands are allowed again).
    ///
    /// # Errors
    /// [`ReservationError::NotFound`] or a storage failure.
    pub fn complete_cleanup(&self, cleanup: &Cleanup) -> Result<(), ReservationError> {
        let id = cleanup.reservation.id;
        let mut r = self.store.get_reservation(id)?.ok_or(ReservationError::NotFound(id))?;
        for a in &cleanup.actions {
            if let CleanupAction::DeleteFile { station, owner, kind, name } = a {
                self.store.delete_program(station, owner, *kind, name)?;
            }
        }
        r.cleaned = true;
        self.store.update_reservation(&r)?;
        tracing::info!(id, station = %r.station, user = %r.user, "slot cleanup completed");
        Ok(())
    }
}
