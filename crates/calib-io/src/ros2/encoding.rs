//! [`Encoding`]: which messages calib reads, known by their message encoding and type name
//! alone, so that the MCAP reader (from its channel records) and the bag reader (from its
//! `topics` table) accept the same topics.

use crate::mcap_log::cdr::{JointFormat, Scalar};
use crate::mcap_log::{DYNAMIC_JOINT_STATE_SCHEMA, JOINT_STATE_SCHEMA};

/// How a topic's messages are decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Encoding {
    /// Joint positions by joint name: JointState (CDR or ROS 1) or DynamicJointState.
    JointState(JointFormat),
    Json,
    /// A `std_msgs` scalar (CDR or ROS 1): one channel, named after the topic.
    Scalar(Scalar),
    /// Numeric fields named by path (`TOPIC.field.path`), read through the message definition
    /// (see [`crate::mcap_log::msgdef`]); added by
    /// [`Registry::read_wanted_fields`](super::registry::Registry::read_wanted_fields), never met
    /// by type.
    Field,
}

impl Encoding {
    /// The encoding of an MCAP channel's messages, if calib reads them.
    pub(crate) fn of(channel: &mcap::Channel) -> Option<Self> {
        let schema = channel.schema.as_ref().map_or("", |s| s.name.as_str());
        Self::from_names(&channel.message_encoding, schema)
    }

    /// The encoding of a channel with this message encoding and schema name, if calib reads it.
    pub(crate) fn from_names(message_encoding: &str, schema: &str) -> Option<Self> {
        let joint_state = schema == JOINT_STATE_SCHEMA || schema == "sensor_msgs/JointState";
        match message_encoding {
            // ROS 1 style names appear in bags converted with older tools.
            "cdr" if joint_state => Some(Encoding::JointState(JointFormat::Cdr)),
            // `mcap convert` of a ROS 1 bag.
            "ros1" if joint_state => Some(Encoding::JointState(JointFormat::Ros1)),
            "cdr"
                if schema == DYNAMIC_JOINT_STATE_SCHEMA
                    || schema == "control_msgs/DynamicJointState" =>
            {
                Some(Encoding::JointState(JointFormat::Dynamic))
            }
            "json" => Some(Encoding::Json),
            // A ROS 1 bag's, or `mcap convert` of one: the value alone, no header.
            "cdr" | "ros1" => Scalar::of_type(schema).map(Encoding::Scalar),
            _ => None,
        }
    }
}
