"""Two images compared: the verdict and its numbers, the 3×3 neighbourhood rule, the heat-maps, and PPM and PNG files
read as a student's image."""
