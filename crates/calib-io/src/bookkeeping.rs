//! Topics every ROS 2 recording carries that hold no encoder readings: the log's messages, the
//! parameter and lifecycle events, the transform tree, diagnostics, the clock and the robot's
//! description. calib skips them like any topic it does not read, and lists them in
//! `calib inspect`, but does not warn about them: a warning is for a topic that might have held
//! the data the user meant (a message type calib does not know).

/// The topics skipped without a warning, by exact name; every topic under [`EVENTS`] too.
pub const BOOKKEEPING_TOPICS: [&str; 7] = [
    "/rosout",
    "/parameter_events",
    "/tf",
    "/tf_static",
    "/diagnostics",
    "/clock",
    "/robot_description",
];

/// The prefix of event topics (`/events/write_split`, …), skipped without a warning.
pub const EVENTS: &str = "/events/";

/// Whether `topic` is one of ROS's bookkeeping topics (`/rosout`, `/parameter_events`, `/tf`,
/// `/tf_static`, `/diagnostics`, `/clock`, `/robot_description`) or an event topic (`/events/…`).
pub fn is_bookkeeping(topic: &str) -> bool {
    BOOKKEEPING_TOPICS.contains(&topic) || topic.starts_with(EVENTS)
}

#[cfg(test)]
mod tests {
    use super::is_bookkeeping;

    #[test]
    fn ros_infrastructure_is_bookkeeping_and_encoder_topics_are_not() {
        for t in ["/rosout", "/tf_static", "/events/write_split", "/clock"] {
            assert!(is_bookkeeping(t), "{t}");
        }
        for t in [
            "/joint_states",
            "/rosout_agg",
            "/events",
            "/motor/state",
            "/tf/extra",
        ] {
            assert!(!is_bookkeeping(t), "{t}");
        }
    }
}
