//! The least decode of a ROS 2 JointState, shared by the floors (`mcap_floor`, `bag_floor`).

/// The positions of a CDR-encoded `sensor_msgs/msg/JointState`, added to `sum`; `None` where the
/// message is not one.
pub fn positions(data: &[u8], sum: &mut f64) -> Option<usize> {
    let little = match data.get(..2)? {
        [0, 1] => true,
        [0, 0] => false,
        _ => return None,
    };
    let body = &data[4..];
    let u32_at = |at: usize| -> Option<u32> {
        let b: [u8; 4] = body.get(at..at + 4)?.try_into().ok()?;
        Some(if little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    };
    let align = |at: usize, to: usize| at.div_ceil(to) * to;
    // header.stamp (sec, nanosec), then header.frame_id.
    let mut at = 8;
    at += 4 + u32_at(at)? as usize;
    // name: string[]
    at = align(at, 4);
    let names = u32_at(at)? as usize;
    at += 4;
    for _ in 0..names {
        at = align(at, 4);
        at += 4 + u32_at(at)? as usize;
    }
    // position: float64[]
    at = align(at, 4);
    let count = u32_at(at)? as usize;
    at = align(at + 4, 8);
    for k in 0..count {
        let b: [u8; 8] = body.get(at + 8 * k..at + 8 * k + 8)?.try_into().ok()?;
        *sum += if little {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        };
    }
    Some(count)
}
