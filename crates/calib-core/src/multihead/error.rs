//! Why a multi-head calibration cannot be made.

/// Why a multi-head calibration cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MultiheadError {
    /// The first head moved but never turned a whole revolution: the likely reason the solve
    /// failed (`cause`).
    #[error("the first head {turn}")]
    NoWholeTurn {
        /// Its travel.
        turn: crate::PartialTurn,
        /// The error the solve gave.
        #[source]
        cause: Box<MultiheadError>,
    },
    /// Fewer than two heads.
    #[error("{found} head(s) given; a multi-head calibration needs at least 2 heads on the scale")]
    TooFewHeads {
        /// Heads given.
        found: usize,
    },
    /// One head named twice.
    #[error("head `{name}` is named twice; name each head once")]
    DuplicateHead {
        /// The repeated name.
        name: String,
    },
    /// A nominal angle that is not a number.
    #[error("head `{head}` has no finite nominal angle")]
    NonFiniteAngle {
        /// The head.
        head: String,
    },
    /// Options that cannot work.
    #[error("invalid options: {0}")]
    Options(String),
    /// An EDA set of fewer than two heads.
    #[error("EDA set {{{}}} has fewer than 2 heads; a set is the first head and the heads equally spaced with it", set.join(", "))]
    SetTooSmall {
        /// The set's heads.
        set: Vec<String>,
    },
    /// An EDA set without the first head.
    #[error("EDA set {{{}}} does not hold the first head `{first}`: the map is the one the first head reads, so every set must include it", set.join(", "))]
    SetWithoutFirstHead {
        /// The set's heads.
        set: Vec<String>,
        /// The first head.
        first: String,
    },
    /// An EDA set whose heads are not equally spaced.
    #[error(
        "EDA set {{{}}}: head `{head}` sits at {angle_deg:.4}° from the first head, not at a multiple of 360°/{count} = {step_deg:.4}° \
         (or shares its place with another head of the set); EDA needs the set's heads equally spaced",
        set.join(", ")
    )]
    SetNotEquallySpaced {
        /// The set's heads.
        set: Vec<String>,
        /// The offending head.
        head: String,
        /// Its nominal angle from the first head, degrees.
        angle_deg: f64,
        /// Heads in the set.
        count: usize,
        /// The spacing they should have, degrees.
        step_deg: f64,
    },
    /// EDA without a set: no heads equally spaced with the first head.
    #[error(
        "no heads are equally spaced with the first head `{first}` (EDA needs e.g. one at 180°, or two at 120° and 240°); \
         check the angles in the `heads` option, or use the joint method, which takes any spacing"
    )]
    NoEquallySpacedSet {
        /// The first head.
        first: String,
    },
    /// No sample with finite readings of every head.
    #[error("no sample has a finite reading of every head ({skipped} skipped); check the channels")]
    NoSamples {
        /// Samples skipped for non-finite readings.
        skipped: u64,
    },
    /// The first head's readings leave part of the circle without samples.
    #[error(
        "the readings of the first head `{first}` leave {gap_deg:.2}° around {at_deg:.2}° without samples; \
         record at least one whole revolution"
    )]
    NotCovered {
        /// The first head.
        first: String,
        /// The largest gap, degrees.
        gap_deg: f64,
        /// Its middle, degrees.
        at_deg: f64,
    },
    /// The requested order needs denser sampling.
    #[error(
        "order {requested} needs the first head's readings to fill {needed} equal bins per revolution, but they fill only \
         {available}; lower the `max_order` option or record more samples per revolution"
    )]
    TooFewSamplesPerRevolution {
        /// The order asked for.
        requested: usize,
        /// Bins it needs (4 per period).
        needed: usize,
        /// Bins the log fills.
        available: usize,
    },
    /// A head's difference to the first head is far from its nominal angle.
    #[error(
        "head `{head}` reads {measured_deg:.4}° from the first head on average, neither 0 (readings relative to its nominal \
         angle) nor its nominal {nominal_deg:.4}° (raw scale readings), to within {tol_deg}°; check its angle in the `heads` option"
    )]
    HeadAngleMismatch {
        /// The head.
        head: String,
        /// Its mean difference to the first head, degrees in `[−180, 180)`.
        measured_deg: f64,
        /// Its nominal angle from the first head, degrees.
        nominal_deg: f64,
        /// The tolerance, degrees.
        tol_deg: f64,
    },
    /// A head's difference to the first head changes too much: not the same scale.
    #[error(
        "the difference between head `{head}` and the first head `{first}` changes by {change_deg:.4}° over the log \
         (at most {tol_deg}° allowed): both must read the same scale, count the same way round and be in the same unit"
    )]
    NotFollowing {
        /// The head.
        head: String,
        /// The first head.
        first: String,
        /// Range of the difference, degrees.
        change_deg: f64,
        /// The tolerance, degrees.
        tol_deg: f64,
    },
    /// The fit's residual is far above the heads' noise and no order stands above it: the map
    /// (zero) explains none of the data.
    #[error(
        "the fit leaves {residual_arcsec:.4}″ RMS per sample where the differences to the first head scatter by \
         {noise_arcsec:.4}″ within the bins (more than 10× the noise), and no order of the map stands above the noise: \
         the map cannot explain the data. Most likely the scale's error lies above the highest order fitted (raise the \
         `max_order` option) or a head is not where the `heads` option says"
    )]
    Unexplained {
        /// RMS of the fit's residual per sample, arcsec.
        residual_arcsec: f64,
        /// The differences' scatter within the bins, arcsec per sample.
        noise_arcsec: f64,
    },
    /// Every order is blind or ill-conditioned.
    #[error(
        "no order up to {max_order} is observable with these head angles (all heads at multiples of 360°/h for every h); \
         the heads must not all sit at one place"
    )]
    NothingObservable {
        /// The highest order tried.
        max_order: usize,
    },
}
