//! MCAP logs: ROS 2 `sensor_msgs/msg/JointState` and `std_msgs` scalars (CDR), and JSON messages.
//!
//! [`McapReader`] streams a recorded MCAP file into [`Sample`](calib_core::Sample)s;
//! [`McapWriter`] writes samples as JointState messages (for `calib simulate`); [`crate::apply`]
//! rewrites an existing file record by record.
//!
//! # What is read
//! - **JointState** (message encoding `cdr`, schema `sensor_msgs/msg/JointState`): each entry of
//!   `name` is a channel, its `position` the reading in radians. The time is `header.stamp`, or
//!   the message's log time where the stamp is zero (publishers that never set it). `velocity` and
//!   `effort` are checked for well-formedness and otherwise ignored.
//! - **JSON** (message encoding `json`): each numeric top-level field is a channel, in the unit of
//!   [`ReadOptions::unit`](crate::ReadOptions::unit) (degrees if `None`); other fields are ignored.
//!   The time is the message's log time.
//! - **`std_msgs` scalars** (message encoding `cdr`, schema `std_msgs/msg/Float64`, `Float32`,
//!   `Int64`, `Int32`, `UInt32` or `UInt16`): the topic is one channel named after it (see
//!   [`crate::naming`]), its `data` in the unit of [`ReadOptions::unit`](crate::ReadOptions::unit)
//!   (degrees if `None`; raw counts with `counts:N`). The time is the message's log time (these
//!   messages carry no header).
//! - **Other topics** (images, TF, protobuf, ...) are skipped and listed by
//!   [`McapReader::ignored_topics`]: a recording usually carries much more than the encoders, and
//!   that is no reason to refuse it. Only a file without any usable topic is an error.
//!
//! A topic's channel set is gathered from its first messages (see [`McapReader::open`]); a
//! JointState message may carry any subset of it (several publishers sharing `/joint_states`),
//! and each joint is then its own time series. A later message naming a joint never seen before
//! is an error, since a channel list that changes under a calibration would corrupt it. JSON
//! messages must give every field of the topic's first message.
//!
//! # Channels on several topics
//! Channels are named as [`crate::naming`] says (the joint name where unique, else
//! `TOPIC/JOINT`). Channels on several topics, or joints published in separate messages, are
//! aligned on the first selected channel's stamps by [`crate::align`]: an exact stamp is kept,
//! any other interpolated (quintic) from the channel's own samples, never across a gap and never
//! extrapolated; what cannot be aligned is counted in [`McapReader::alignment`].
//!
//! # Damaged files
//! A file that ends early (a crashed recording) yields every message before the break; the break
//! is recorded in [`ReadDiagnostics::truncated`](crate::ReadDiagnostics::truncated) so the caller
//! can warn. Keeping the data is what a user wants from an hour-long run that crashed in its
//! last second. Its [`byte_offset`](crate::Truncation::byte_offset) is where reading stopped: the
//! messages read came from the bytes before it, and nothing from it to the end of the file could
//! be read. That is the start of the first incomplete record or, if the cut falls inside a chunk,
//! the point in the chunk up to which its data had been read when its last whole message came
//! out: chunks, compressed or not, are decoded as they stream, so the messages of a cut chunk
//! before the cut are kept too (a compressed one up to its last whole compressed block). An empty file, a file that is not MCAP, and corruption inside the data are errors.

pub(crate) mod cdr;
pub(crate) mod chunk_write;
pub(crate) mod chunks;
pub(crate) mod json;
pub(crate) mod msgdef;
pub(crate) mod read;
pub(crate) mod records;
mod write;

pub use crate::ros2::PEEK_WINDOW;
pub use crate::ros2::registry::{IgnoredTopic, TopicInfo};
pub use read::McapReader;
pub use write::{DEFAULT_TOPIC, McapWriter};

/// The ROS 2 type name of joint states.
pub const JOINT_STATE_SCHEMA: &str = "sensor_msgs/msg/JointState";

/// The ROS 2 type name of `ros2_control`'s joint states with all their interfaces.
pub const DYNAMIC_JOINT_STATE_SCHEMA: &str = "control_msgs/msg/DynamicJointState";

/// The `ros2msg` definition of `sensor_msgs/msg/JointState` with its dependencies, as rosbag2
/// stores it in the schema record.
pub const JOINT_STATE_MSGDEF: &str = "\
std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";
