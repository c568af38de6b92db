//! The paper's design steps, in the order of its Methods (Martinez et al., sections
//! 2.3.3-2.4.6); [`crate::design::design`] runs them one after the other:
//!
//! 1. [`seam`]: the attachment seam, from the surgeon's suture points (2.3.3);
//! 2. [`partition`]: cut along the seam, keep the tunnel's wall, remesh it (2.3.3);
//! 3. [`patch`]: the initial patch spanning the seam (2.3.3);
//! 4. [`centerline`]: the tunnel's centerline between the caps (2.4.2);
//! 5. [`sections`]: the tunnel's cross-sections normal to it (2.4.3);
//! 6. [`amplitudes`]: how far each section's baffle arc must bulge for the target (2.4.4);
//! 7. [`envelope`]: the amplitudes' least concave majorant along the tunnel (2.4.5);
//! 8. [`surface`]: the final baffle and the watertight VSD-to-aorta domain (2.4.6).
//!
//! A step uses the geometry helpers ([`crate::geometry`]) and the steps before it, never
//! the design that runs it or the analyses after it.

pub mod seam;
pub mod partition;
pub mod patch;
pub mod centerline;
pub mod sections;
pub mod amplitudes;
pub mod envelope;
pub mod surface;
