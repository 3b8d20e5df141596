"""What a course hands phongray: its folders, opened once and read through; the LMS layouts; students' files read as
untrusted input; and the teaching assistant's mistakes (ClassError)."""
