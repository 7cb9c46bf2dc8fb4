"""What a camera sees: projection, imaging noise, marker tracker, the camera chain, optical flow."""
